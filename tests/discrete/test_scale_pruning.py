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
