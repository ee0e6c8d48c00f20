"""The stop census of experiments/bench/stop_census.py: a stop put against the plan's waits and turns."""

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parents[2] / "experiments" / "bench"))
from stop_census import classify, stop_steps  # noqa: E402

from mrfswarm.trajectory.polynomial import PiecewisePolynomial  # noqa: E402


def moves(text: str) -> np.ndarray:
    """(T, 2) moves from symbols: - right, ^ up, v down, < left, / up-right, . wait."""
    table = {"-": (1, 0), "^": (0, 1), "v": (0, -1), "<": (-1, 0), "/": (1, 1), ".": (0, 0)}
    return np.array([table[c] for c in text])


def test_waits_are_classed_by_their_run_and_the_turn_around_it():
    assert classify(moves("--..--"), 2) == "wait 2-8, <90"
    assert classify(moves("--..^-"), 3) == "wait 2-8, >=90"
    assert classify(moves("-" + "." * 9 + "<"), 5) == "wait >8, >=90"
    assert classify(moves("-./-"), 1) == "wait 1, <90"
    assert classify(moves("-./-"), 2) == "wait 1, <90"  # the step after the wait: still that wait
    assert classify(moves("..--"), 0) == "wait 2-8, -"  # the run starts the plan


def test_a_stop_while_moving_reports_the_turn():
    assert classify(moves("--<<"), 2) == "moving 180"
    assert classify(moves("--^^"), 2) == "moving 90"


def test_a_stop_is_found_in_its_step():
    # speed (t - 1.5)^2 on [0, 3]: below 0.05 m/s from t = 1.28 to 1.72, inside the flight; steps of 1 s
    tr = PiecewisePolynomial(np.array([3.0]), np.array([[0.0, 2.25, -1.5, 1.0 / 3.0]]))
    assert stop_steps(tr, np.array([0.0, 1.0, 2.0, 3.0]), 50.0, 0.05) == [1]
    # never slower than 0.05 m/s: no stop
    steady = PiecewisePolynomial(np.array([3.0]), np.array([[0.0, 1.0, 0.0, 0.0]]))
    assert stop_steps(steady, np.array([0.0, 1.0, 2.0, 3.0]), 50.0, 0.05) == []
