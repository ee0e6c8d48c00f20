"""The ordered schedule of experiments/bench/timing_headroom.py: who waits for whom."""

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parents[2] / "experiments" / "bench"))
from timing_headroom import ordered_makespan  # noqa: E402


def boxes(centres: list) -> tuple[np.ndarray, np.ndarray]:
    """(T, N, 2) lower and upper corners of 0.8 m squares around ``centres`` (T, N, 2)."""
    c = np.asarray(centres, dtype=float)
    return c - 0.4, c + 0.4


def test_robots_far_apart_keep_their_own_time_lines():
    need = np.array([[1.0, 0.5], [1.0, 0.5], [0.0, 3.0]])
    lo, hi = boxes([[[0, 0], [10, 0]], [[1, 0], [11, 0]], [[1, 0], [12, 0]]])
    assert ordered_makespan(need, lo, hi, 0.5) == pytest.approx(4.0)  # robot 1: 0.5 + 0.5 + 3


def test_a_robot_waits_for_the_earlier_step_of_a_robot_near_it():
    # robot 0 crosses (5, 0) in step 0 and leaves; robot 1 comes within 0.5 m of that only in step 2
    need = np.array([[4.0, 0.1], [0.1, 0.1], [0.1, 1.0]])
    near = [[[5, 0], [5, 3]], [[9, 0], [5, 2]], [[12, 0], [5, 0.9]]]
    # robot 1's step 2 starts when robot 0's step 0 has ended (4 s) and lasts 1 s
    assert ordered_makespan(need, *boxes(near), 0.5) == pytest.approx(5.0)
    far = [[[5, 0], [5, 3]], [[9, 0], [5, 2]], [[12, 0], [5, 1.5]]]
    assert ordered_makespan(need, *boxes(far), 0.5) == pytest.approx(4.2)  # robot 0's 4 + 0.1 + 0.1


def test_robots_near_each_other_in_one_step_share_its_interval():
    need = np.array([[1.0, 3.0], [0.2, 2.0], [1.0, 0.0]])
    near = [[[0, 0], [1, 0]], [[0, 5], [1, 5]], [[0, 9], [1, 20]]]
    # step 0: both last 3 s; step 1: near again, both 2 s; robot 0's step 2 then ends at 6 s
    assert ordered_makespan(need, *boxes(near), 0.5) == pytest.approx(6.0)
    apart = [[[0, 0], [1, 0]], [[0, 5], [1, 25]], [[0, 9], [1, 20]]]
    assert ordered_makespan(need, *boxes(apart), 0.5) == pytest.approx(5.0)  # robot 1: 3 + 2; robot 0: 4.2
