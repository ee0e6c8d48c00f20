"""Following into the cells robots leave (``mrf.follow``) and the end on arrival (``mrf.arrival``)."""

from __future__ import annotations

import numpy as np
import pytest

from mrfswarm.discrete.goal_distance import goal_distance
from mrfswarm.discrete.label_sets import label_sets
from mrfswarm.discrete.planner import DiscreteProblem, mrf_step, plan_discrete
from mrfswarm.discrete.potentials import Morse
from mrfswarm.discrete.safety import discrete_violations


def corridor_queue(follow: bool, n: int = 4, length: int = 16) -> DiscreteProblem:
    """n robots nose to tail in a 1-cell corridor, the goal at its far end."""
    free = np.zeros((length, 3), dtype=bool)
    free[:, 1] = True
    start = np.array([[i, 1] for i in range(n)])
    goal = np.array([length - 1, 1])
    d = goal_distance(free, goal)
    static = np.where(d.reachable, 3.0 * np.exp(np.where(d.reachable, d.path, 0.0) / 20.0), np.inf)
    return DiscreteProblem(free=free, static=static, start=start, goal=goal, morse=Morse(), k=1, order=2,
                           follow=follow, goal_path=d.path, goal_region_radius=float(n))


def test_a_queue_moves_as_a_whole_when_following():
    moved = {}
    for follow in (False, True):
        out = mrf_step(corridor_queue(follow), corridor_queue(follow).start)
        moved[follow] = out.moved
    assert moved[False] == 1  # the paper's label sets: only the head has a free cell ahead
    assert moved[True] == 4  # every robot takes the cell the one ahead leaves, in the same step


def test_following_shares_only_the_cells_robots_stand_in():
    starts = np.array([[0, 1], [1, 1], [5, 1]])
    free = np.ones((8, 3), dtype=bool)
    ls = label_sets(free, starts, 2, follow=True)
    cells = [{tuple(c) for c, v in zip(ls.cells[i], ls.valid[i]) if v} for i in range(3)]
    assert (1, 1) in cells[0] and (1, 1) in cells[1]  # robot 1's cell: its stay, and robot 0 may follow
    shared = (cells[0] & cells[1]) | (cells[0] & cells[2]) | (cells[1] & cells[2])
    assert shared <= {tuple(s) for s in starts}  # every other cell still goes to one robot only
    ls0 = label_sets(free, starts, 2, follow=False)
    assert not any((1, 1) == tuple(c) for c, v in zip(ls0.cells[0], ls0.valid[0]) if v)


@pytest.mark.parametrize("follow", [False, True])
def test_the_queue_is_safe_and_following_reaches_the_goal_sooner(follow):
    problem = corridor_queue(follow)
    plan = plan_discrete(problem, max_steps=60, arrival=True)
    assert discrete_violations(plan.paths, problem.free) == []
    assert plan.stop_reason == "arrived" and plan.converged
    # the tail (cell 0) is in the goal region (4 cells of path from cell 15) at cell 11
    if follow:
        assert plan.n_steps == 11  # every step moves the whole queue
    else:
        assert plan.n_steps > 11


def test_the_plan_ends_at_the_first_step_with_every_robot_in_the_goal_region():
    problem = corridor_queue(True)
    plan = plan_discrete(problem, max_steps=60, arrival=True)
    d = problem.goal_path[plan.paths[..., 0], plan.paths[..., 1]]
    inside = (d <= problem.goal_region_radius).all(axis=1)
    assert inside[-1] and not inside[:-1].any()  # arrived at the last step, not one step earlier
    longer = plan_discrete(problem, max_steps=60, arrival=False)
    assert longer.stop_reason != "arrived" and longer.n_steps > plan.n_steps
    np.testing.assert_array_equal(longer.paths[:len(plan.paths)], plan.paths)  # the same plan, cut short


def test_a_swarm_that_starts_in_the_goal_region_takes_no_step():
    """Every robot in the goal region at the start: the arrival was checked only after a step, and one robot moved
    (a 2.7 s flight at 3.8 x its lower bound for nothing)."""
    problem = corridor_queue(True)
    from dataclasses import replace

    there = replace(problem, start=np.array([[15, 1], [14, 1], [13, 1], [12, 1]]))
    plan = plan_discrete(there, max_steps=60, arrival=True)
    assert plan.stop_reason == "arrived" and plan.converged and plan.n_steps == 0
    np.testing.assert_array_equal(plan.paths, there.start[None])
    assert len(plan.energy) == 1 and np.isfinite(plan.energy[0])


def test_a_swarm_cut_off_from_the_goal_has_not_arrived():
    """No robot has a free path to the goal (a wall across the map, the euclidean field pulling at it): the
    arrival rule has no robot to wait for, and the plan must not end "arrived" after one step."""
    free = np.ones((20, 10), dtype=bool)
    free[10, :] = False
    goal = np.array([16, 5])
    start = np.array([[3, 4], [3, 6], [5, 4], [5, 6]])
    d = goal_distance(free, goal)
    assert not d.reachable[tuple(start.T)].any()
    xs, ys = np.meshgrid(np.arange(20), np.arange(10), indexing="ij")
    static = np.where(free, 3.0 * np.hypot(xs - goal[0], ys - goal[1]) / 20.0, np.inf)
    problem = DiscreteProblem(free=free, static=static, start=start, goal=goal, morse=Morse(), k=2, order=2,
                              goal_path=d.path, goal_region_radius=3.0)
    plan = plan_discrete(problem, max_steps=30, arrival=True)
    assert plan.stop_reason != "arrived"
    assert plan.n_steps > 1  # it moved toward the wall, as the energy asks
    assert discrete_violations(plan.paths, free) == []
