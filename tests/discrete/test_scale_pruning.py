"""Indexed waypoint pruning equals the all-pairs reference (its oracle) on random swarms."""

import numpy as np
import pytest

from mrfswarm.discrete.motion import stencil
from mrfswarm.discrete.planner import DiscreteProblem, plan_discrete
from mrfswarm.discrete.potentials import Morse
from mrfswarm.discrete.pruning import horizon_bounds, prune_paths, prune_paths_brute_force, prune_robot
from support.swarms import random_start


def wandering(rng, n, steps, W=25, H=25, order=2):
    """Robots on distinct cells taking random stencil moves (a pruning input need not be a valid plan)."""
    free, pos = random_start(rng, n, W, H, 0.15)
    off = stencil(order)
    paths = [pos]
    for _ in range(steps):
        pos = np.clip(pos + off[rng.integers(0, len(off), n)], 0, [W - 1, H - 1])
        paths.append(pos)
    return np.stack(paths), free


@pytest.mark.parametrize("seed", range(10))
def test_prune_paths_equals_all_pairs(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 40))
    paths, free = wandering(rng, n, int(rng.integers(0, 11)), order=int(rng.choice([1, 2, 4])))
    horizon = int(rng.integers(1, 6))
    ref = prune_paths_brute_force(paths, free, horizon)
    got = prune_paths(paths, free, horizon)
    assert [g.tolist() for g in got] == [r.tolist() for r in ref]
    T = len(paths) - 1
    for i in rng.choice(n, min(n, 4), replace=False):
        for a, b in horizon_bounds(T, horizon):
            assert prune_robot(paths, free, int(i), a, b) == [k for k in ref[i].tolist() if a <= k <= b]


def test_prune_paths_on_a_planned_crossing():
    """A real plan: dense swarm, many chords blocked by neighbours' moves; equal to the reference."""
    rng = np.random.default_rng(3)
    W, H = 40, 20
    free = np.ones((W, H), bool)
    free[18:21, 0:7] = False
    cells = np.unique(np.round(rng.normal([8, 10], 2.5, (60, 2))).astype(int), axis=0)[:30]
    goal = np.array([34, 10])
    static = np.hypot(*(np.indices((W, H)) - goal[:, None, None]))
    plan = plan_discrete(DiscreteProblem(free=free, static=static, start=cells, goal=goal, morse=Morse(), k=5,
                                         order=2), max_steps=30)
    ref = prune_paths_brute_force(plan.paths, free, 4)
    assert [g.tolist() for g in prune_paths(plan.paths, free, 4)] == [r.tolist() for r in ref]
    assert sum(len(r) for r in ref) < len(ref) * len(plan.paths)  # something was pruned
    assert sum(len(r) for r in ref) > len(ref) * len(horizon_bounds(len(plan.paths) - 1, 4)) + len(ref)  # not all


@pytest.mark.parametrize("seed", range(10, 30))
def test_prune_paths_dense_swarms_equal_all_pairs(seed):
    """Crowded small maps (most chords meet another robot's moves), the real horizon of 8 steps among others."""
    rng = np.random.default_rng(seed)
    W = int(rng.integers(6, 14))
    n = int(rng.integers(2, W * W // 3))
    paths, free = wandering(rng, n, int(rng.integers(1, 18)), W=W, H=W, order=int(rng.choice([1, 2, 4])))
    for horizon in (1, 2, int(rng.integers(3, 10)), 8):
        ref = prune_paths_brute_force(paths, free, horizon)
        assert [g.tolist() for g in prune_paths(paths, free, horizon)] == [r.tolist() for r in ref]


def _prune_both(paths, horizon, free=None):
    paths = np.asarray(paths)
    free = np.ones((8, 8), bool) if free is None else free
    ref = [r.tolist() for r in prune_paths_brute_force(paths, free, horizon)]
    assert [g.tolist() for g in prune_paths(paths, free, horizon)] == ref
    return ref


def test_chord_crossing_a_move_between_cells():
    """Robot 0's chord (0,0)-(2,1) meets robot 1's move (1,1)-(1,0) at (1, 0.5), a point on no cell."""
    a = [(0, 0), (1, 0), (2, 1)]
    b = [(1, 1), (1, 0), (1, 0)]
    assert _prune_both(np.stack([a, b], axis=1), 2)[0] == [0, 1, 2]
    c = [(1, 2), (1, 3), (1, 3)]  # moved away: the chord is free
    assert _prune_both(np.stack([a, c], axis=1), 2)[0] == [0, 2]


def test_chord_from_a_cell_another_robot_passes_over():
    """Robot 1 jumps (0,1)-(2,1) over (1,1), where robot 0's chord starts: they touch; one cell higher they do not."""
    a = [(1, 1), (2, 2), (3, 3)]
    for b, expected in (([(0, 1), (2, 1), (2, 0)], [0, 1, 2]), ([(0, 0), (2, 0), (3, 0)], [0, 2])):
        assert _prune_both(np.stack([a, b], axis=1), 2)[0] == expected


def test_chord_through_a_cell_visited_at_another_time():
    """Robot 1 stood on (1,0) at step 0, robot 0's chord (0,0)-(2,0) passes it later: blocked (the trajectory, not the time)."""
    a = [(0, 0), (1, 1), (2, 0)]
    b = [(1, 0), (1, 2), (1, 3)]
    assert _prune_both(np.stack([a, b], axis=1), 2)[0] == [0, 1, 2]


def test_own_cells_and_standing_still_do_not_block():
    """A robot returning to its cells, and robots that never move (zero-length chords), keep only the horizon's ends."""
    a = [(0, 0), (1, 0), (2, 0), (1, 0), (0, 0)]
    still = [(5, 5)] * 5
    got = _prune_both(np.stack([a, still], axis=1), 4)
    assert got == [[0, 4], [0, 4]]


def test_one_robot_no_steps_and_a_blocked_map():
    free = np.ones((8, 8), bool)
    free[1:3, 1] = False
    assert _prune_both([[(0, 0)]], 3) == [[0]]  # no steps
    assert _prune_both(np.zeros((1, 3, 2), int) + np.arange(3)[None, :, None], 8) == [[0], [0], [0]]
    walk = np.array([(0, 0), (1, 0), (2, 0), (3, 1), (3, 2)])[:, None]
    assert _prune_both(walk, 4, free) == [[0, 2, 3, 4]]  # (0,0)-(3,2) and (0,0)-(3,1) come too near the wall, (0,0)-(2,0) keeps half a cell
