"""``mrf.contested = "queue"``: the label sets of ``"shared"``, and the robots that have waited longest visited first
by the step's optimizer, so a robot waiting beside a file of moving robots takes the cell it needs when that cell
is free (a zipper merge) instead of the next robot of the file."""

from __future__ import annotations

import numpy as np
import pytest

from mrfswarm.discrete.goal_distance import goal_distance
from mrfswarm.discrete.planner import DiscreteProblem, mrf_step, plan_discrete
from mrfswarm.discrete.potentials import Morse
from mrfswarm.discrete.safety import discrete_violations


def side_pocket(contested: str) -> DiscreteProblem:
    """A 1-cell corridor along y = 1 to the goal at its end, and a 1-cell pocket above cell (4, 1): robot 0 in the
    corridor at (3, 1), robot 1 in the pocket at (4, 2). Both need (4, 1) next, each by a straight move, and they
    are equally far from the goal."""
    free = np.zeros((10, 3), dtype=bool)
    free[:, 1] = True
    free[4, 2] = True
    goal = np.array([9, 1])
    d = goal_distance(free, goal)
    static = np.where(d.reachable, 3.0 * np.exp(np.where(d.reachable, d.path, 0.0) / 20.0), np.inf)
    start = np.array([[3, 1], [4, 2]])
    return DiscreteProblem(free=free, static=static, start=start, goal=goal, morse=Morse(), k=1, order=2,
                           contested=contested, goal_distance=d.path, goal_path=d.path, goal_region_radius=1.0)


@pytest.mark.parametrize("waited, winner", [([0, 5], 1), ([5, 0], 0), ([2, 3], 1)])
def test_the_robot_that_waited_longer_takes_the_cell_both_need(waited, winner):
    problem = side_pocket("queue")
    out = mrf_step(problem, problem.start, waited=np.array(waited))
    assert tuple(out.positions[winner]) == (4, 1)
    assert np.array_equal(out.positions[1 - winner], problem.start[1 - winner])


def test_shared_ignores_the_waits():
    problem = side_pocket("shared")
    moved = {tuple(mrf_step(problem, problem.start, waited=np.array(w)).positions[1]) for w in ([0, 5], [5, 0])}
    assert len(moved) == 1  # the same robot takes the cell either way


@pytest.mark.parametrize("contested", ["queue", "shared"])
def test_both_robots_reach_the_goal_safely(contested):
    problem = side_pocket(contested)
    plan = plan_discrete(problem, max_steps=30, arrival=True)
    assert plan.stop_reason == "arrived" and plan.contested == contested
    assert discrete_violations(plan.paths, problem.free) == []

