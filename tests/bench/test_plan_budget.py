"""The move census of experiments/bench/plan_budget.py: which move each robot took, against the best one."""

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parents[2] / "experiments" / "bench"))
from plan_budget import move_census  # noqa: E402


def test_each_kind_of_move_is_counted_once():
    """A field falling towards x = 0, steepest towards y = 3: one robot takes its best cell, one waits, and one
    each misses its best cell because another robot stands in it, moves into it, or for no robot at all."""
    free = np.ones((14, 12), dtype=bool)
    xs, ys = np.meshgrid(np.arange(14), np.arange(12), indexing="ij")
    distance = xs + 0.01 * np.abs(ys - 3)
    before = [(5, 2), (8, 2), (8, 6), (7, 5), (8, 9), (6, 8), (12, 2)]
    after = [(4, 3), (8, 2), (8, 7), (7, 5), (8, 10), (7, 8), (12, 3)]
    # 0 best; 1 and 3 wait; 2's best (7, 5) is occupied by 3; 4's best (7, 8) is taken by 5, whose own best
    # (5, 7) is free, as 6's (11, 3) is
    paths = np.array([before, after])
    counts = move_census(paths, free, distance, near=0.5)
    assert counts == {"best": 1, "wait": 2, "taken": 1, "occupied": 1, "free": 2}
    # robots within ``near`` of the goal are not counted
    assert sum(move_census(paths, free, distance, near=100.0).values()) == 0
