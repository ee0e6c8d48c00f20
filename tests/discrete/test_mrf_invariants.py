"""The discrete safety invariants hold for every MRF method, by brute force.

Every method of ``solvers.mrf.METHODS`` (the registry, never a list of names) plans a few
steps on hypothesis-generated maps and swarms, and the paths are checked by dense
sampling of the straight moves, independently of the planner's geometry, and by
:func:`mrfswarm.discrete.safety.discrete_violations`.

The paper's label-set heuristics (disjoint label sets, cells of other robots removed)
leave real swarm MRFs with almost no conflict pairs, so the conflict handling of the
methods is exercised separately: on synthetic MRFs with many conflicts, and on step MRFs
whose label sets are full, overlapping stencils (every clear move of every robot, other
robots' cells included), where most neighbouring robots share forbidden label pairs.
Methods flagged ``optimal`` (exhaustive search) only get problems small enough for them.

The same properties hold on voxel maps (d = 3) with downwash: every pair of robots one
cell apart in the downwash-scaled metric, at the steps and along the moves.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from mrfswarm.config import GoalPotentialConfig, ObstaclePotentialConfig
from mrfswarm.discrete.label_sets import LabelSets
from mrfswarm.discrete.motion import moves_clear, stencil
from mrfswarm.discrete.planner import DiscreteProblem, graph_weights, plan_discrete
from mrfswarm.discrete.potentials import Morse, static_field
from mrfswarm.discrete.safety import discrete_violations
from mrfswarm.discrete.step_mrf import step_mrf
from mrfswarm.geometry import downwash_scale, norm
from solvers import mrf
from solvers.mrf.exact import MAX_LABELLINGS
from solvers.mrf.synthetic import random_mrf, swarm_mrf
from support.fields import random_map_static

METHODS = mrf.METHODS.names()
#: Exhaustive methods: exponential in N, given tiny problems only.
TINY_ONLY = {b.name for b in mrf.METHODS if b.capabilities.optimal}
ORDERS = [1, 2, 4, 8]
SAMPLES = 201  # per step and robot: a relative speed of <= 2 * sqrt(8) cells/step moves < 0.03 cell between samples


def occupied_squares(free: np.ndarray) -> np.ndarray:
    """Centres of occupied cells (voxels), with a ring of occupied cells around the map (off the map is a wall)."""
    return np.argwhere(~np.pad(free, 1, constant_values=False)) - 1


def brute_force_violations(paths: np.ndarray, free: np.ndarray, downwash: float = 1.0) -> list[str]:
    """The discrete invariants checked by dense sampling, all robot pairs, no library geometry.

    At every step: positions are integer cells on the map, free, pairwise distinct. Within
    every step, with all robots moving straight at the same time: every pair keeps at
    least one cell apart at every sample, and every sample of a moving robot keeps half a
    cell from every occupied square (the planner's wall clearance; off the map counts as
    occupied), so no move enters or cuts an obstacle. Distances between robots are in the
    downwash-scaled metric (z / c on voxel maps).
    """
    out = []
    shape = np.array(free.shape)
    scale = downwash_scale(free.ndim, downwash)
    walls = occupied_squares(free).astype(float)
    paths = np.asarray(paths)
    for t, p in enumerate(paths):
        if not np.issubdtype(p.dtype, np.integer):
            out.append(f"step {t}: positions are not integer cells")
        if np.any((p < 0) | (p >= shape)):
            out.append(f"step {t}: off the map")
            continue
        if not free[tuple(p.T)].all():
            out.append(f"step {t}: a robot in an occupied cell")
        if len({tuple(c) for c in p.tolist()}) != len(p):
            out.append(f"step {t}: two robots share a cell")
        if t == 0:
            continue
        a, b = paths[t - 1].astype(float), p.astype(float)
        s = np.linspace(0.0, 1.0, SAMPLES)[:, None, None]
        pos = a[None] + s * (b - a)[None]  # (S, N, d)
        if len(p) > 1:
            diff = (pos[:, :, None, :] - pos[:, None, :, :]) * scale
            d = np.sqrt((diff**2).sum(-1))
            iu = np.triu_indices(len(p), 1)
            dmin = d[:, iu[0], iu[1]].min()
            if dmin < 1.0 - 1e-9:
                out.append(f"step {t}: two robots {dmin:.3f} cells apart during the step")
        moving = np.any(a != b, axis=1)
        if moving.any() and len(walls):
            pts = pos[:, moving].reshape(-1, free.ndim)
            g = np.maximum(np.abs(pts[:, None, :] - walls[None, :, :]) - 0.5, 0.0)
            clearance = np.sqrt((g**2).sum(-1)).min()
            if clearance < 0.5 - 1e-9:
                out.append(f"step {t}: a move passes {clearance:.3f} cells from an obstacle")
    return out


def check_paths(paths: np.ndarray, free: np.ndarray, downwash: float = 1.0) -> None:
    assert brute_force_violations(paths, free, downwash) == []
    assert discrete_violations(paths, free, downwash=downwash) == []


def test_the_brute_force_check_catches_each_kind_of_violation():
    free = np.ones((8, 8), bool)
    free[4, 4] = False
    assert brute_force_violations(np.array([[[0, 0], [2, 0]], [[1, 0], [3, 0]]]), free) == []  # a convoy
    cases = {
        "during the step": [[[0, 0], [1, 0]], [[1, 1], [0, 1]]],  # diagonal swap: they meet halfway
        "share a cell": [[[0, 0], [2, 2]], [[2, 2], [2, 2]]],
        "occupied cell": [[[3, 4]], [[4, 4]]],
        "from an obstacle": [[[3, 3]], [[5, 5]]],  # diagonal through the obstacle's corner region
        "off the map": [[[0, 0]], [[-1, 0]]],
    }
    for what, paths in cases.items():
        found = brute_force_violations(np.array(paths), free)
        assert any(what in v for v in found), (what, found)
    # a diagonal move between two diagonal obstacles cuts their corners
    free2 = np.ones((4, 4), bool)
    free2[1, 0] = free2[0, 1] = False
    assert any("obstacle" in v for v in brute_force_violations(np.array([[[0, 0]], [[1, 1]]]), free2))


def test_the_brute_force_check_catches_each_kind_of_violation_on_voxels():
    free = np.ones((6, 6, 6), bool)
    free[3, 3, 3] = False
    stacked = np.array([[[0, 0, 0], [0, 0, 2]], [[1, 0, 0], [1, 0, 1]]])  # ends one voxel apart in z
    assert brute_force_violations(stacked, free, downwash=1.0) == []
    assert any("during the step" in v for v in brute_force_violations(stacked, free, downwash=2.0))
    cases = {
        "share a cell": [[[0, 0, 0], [2, 2, 2]], [[2, 2, 2], [2, 2, 2]]],
        "occupied cell": [[[3, 3, 2]], [[3, 3, 3]]],
        "from an obstacle": [[[2, 2, 2]], [[3, 3, 2]], [[4, 4, 3]]],  # past the voxel's edge
        "off the map": [[[0, 0, 0]], [[0, 0, -1]]],
    }
    for what, paths in cases.items():
        found = brute_force_violations(np.array(paths), free)
        assert any(what in v for v in found), (what, found)


# ---------------------------------------------------------------- real swarm plans


def clustered(rng: np.random.Generator, free: np.ndarray, n: int) -> np.ndarray:
    """n distinct free cells near a random free cell (a packed swarm: moves interact)."""
    cells = np.argwhere(free)
    centre = cells[rng.integers(len(cells))]
    d = norm(cells - centre) + rng.random(len(cells)) * 1.5
    return cells[np.argsort(d)[:n]]


@st.composite
def swarm_problems(draw, max_robots: int) -> DiscreteProblem:
    rng = np.random.default_rng(draw(st.integers(0, 2**31 - 1)))
    W, H = draw(st.integers(6, 14)), draw(st.integers(6, 14))
    free = rng.random((W, H)) >= draw(st.floats(0.0, 0.4))
    n_free = int(free.sum())
    assume(n_free >= 3)
    n = draw(st.integers(2, min(max_robots, n_free - 1)))
    start = clustered(rng, free, n)
    goal = None
    if draw(st.booleans()):
        others = np.argwhere(free)
        others = others[~(others[:, None, :] == start[None]).all(axis=2).any(axis=1)]
        goal = others[rng.integers(len(others))]
    order = draw(st.sampled_from(ORDERS))
    static = random_map_static(free, goal, start, draw(st.sampled_from(["geodesic", "euclidean"])), order)
    return DiscreteProblem(free=free, static=static, start=start, goal=goal, morse=Morse(),
                           k=draw(st.integers(1, n - 1)), order=order, follow=draw(st.booleans()))


@pytest.mark.parametrize("method", METHODS)
@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(data=st.data())
def test_every_method_keeps_the_invariants_on_random_maps(method, data):
    check_a_short_plan(data.draw(swarm_problems(max_robots=3 if method in TINY_ONLY else 10)), method)


def check_a_short_plan(problem: DiscreteProblem, method: str) -> None:
    plan = plan_discrete(problem, method=method, max_steps=4, options=mrf.Options(seed=0))
    assert plan.paths.shape[1:] == problem.start.shape and np.array_equal(plan.paths[0], problem.start)
    check_paths(plan.paths, problem.free, problem.downwash)
    if not problem.follow:  # label sets are disjoint: nothing to repair (following shares the cells robots hold)
        assert all(s["repaired"] == 0 for s in plan.steps)


# ---------------------------------------------------------------- conflict-heavy MRFs


def raw_result(m: mrf.PairwiseMRF, method: str, options: mrf.Options) -> mrf.MRFResult:
    """The method's own labelling, before :func:`solvers.mrf.minimize` would repair it."""
    return mrf.METHODS.get(method).entry(m, options)


def without_conflicts(m: mrf.PairwiseMRF) -> mrf.PairwiseMRF:
    return mrf.PairwiseMRF(m.unary, m.edges, m.pairwise, np.zeros((0, 2)), np.zeros((0,) + m.unary.shape[1:] * 2),
                           m.initial)


def apart(cells: np.ndarray, downwash: float) -> np.ndarray:
    """Cells kept greedily, in order, so that every two are >= 1 apart in the downwash-scaled metric."""
    scale = downwash_scale(cells.shape[1], downwash)
    kept: list[np.ndarray] = []
    for c in cells:
        if all(np.linalg.norm((c - k) * scale) >= 1 - 1e-9 for k in kept):
            kept.append(c)
    return np.array(kept)


@st.composite
def voxel_swarm_problems(draw, max_robots: int) -> DiscreteProblem:
    rng = np.random.default_rng(draw(st.integers(0, 2**31 - 1)))
    shape = (draw(st.integers(4, 9)), draw(st.integers(4, 8)), draw(st.integers(3, 6)))
    free = rng.random(shape) >= draw(st.floats(0.0, 0.35))
    downwash = draw(st.sampled_from([1.0, 1.5, 2.0, 3.0]))
    assume(free.sum() >= 4)
    n = draw(st.integers(2, max_robots))
    start = apart(clustered(rng, free, 3 * n), downwash)[:n]
    assume(len(start) >= 2)
    goal = None
    if draw(st.booleans()):
        others = np.argwhere(free)
        others = others[~(others[:, None, :] == start[None]).all(axis=2).any(axis=1)]
        assume(len(others))
        goal = others[rng.integers(len(others))]
    order = draw(st.sampled_from([1, 2, 3, 4]))
    static = random_map_static(free, goal, start, draw(st.sampled_from(["geodesic", "euclidean"])), order)
    return DiscreteProblem(free=free, static=static, start=start, goal=goal, morse=Morse(),
                           k=draw(st.integers(1, len(start) - 1)), order=order, follow=draw(st.booleans()),
                           downwash=downwash)


@pytest.mark.parametrize("method", METHODS)
@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(data=st.data())
def test_every_method_keeps_the_invariants_on_random_voxel_maps(method, data):
    check_a_short_plan(data.draw(voxel_swarm_problems(max_robots=3 if method in TINY_ONLY else 10)), method)


@pytest.mark.parametrize("method", METHODS)
def test_every_method_is_feasible_on_synthetic_mrfs_with_many_conflicts(method):
    rng = np.random.default_rng(11)
    problems = [random_mrf(rng, 6, 4, p_edge=0.7, p_conf=0.9, p_forbid=0.5) for _ in range(8)]
    if method not in TINY_ONLY:
        problems += [swarm_mrf(60, seed=s, density=0.6, conflict_radius=2.9) for s in range(3)]
    binding = 0
    for m in problems:
        assert len(m.conflicts) > 0
        res = raw_result(m, method, mrf.Options(seed=0, max_iter=50))
        assert m.is_feasible(res.labels), f"{method} returned a labelling that breaks a conflict"
        assert res.energy == pytest.approx(m.energy(res.labels), abs=1e-9)
        assert res.energy <= m.energy(m.initial) + 1e-9
        # the conflicts matter: without them, ICM's labelling would break one
        binding += not m.is_feasible(mrf.minimize(without_conflicts(m), "icm").labels)
    assert binding >= len(problems) // 2


def full_stencil_labels(free: np.ndarray, starts: np.ndarray, order: int) -> LabelSets:
    """Every clear move of every robot, other robots' cells and contested cells included."""
    S = len(stencil(order, free.ndim))
    ok = moves_clear(free, starts, np.broadcast_to(np.arange(S), (len(starts), S)), order)
    ok[:, 0] = True
    count = ok.sum(axis=1)
    L = int(count.max())
    index = np.argsort(~ok, axis=1, kind="stable")[:, :L]
    index = np.where(np.arange(L)[None, :] < count[:, None], index, 0)
    return LabelSets(index=index, count=count, starts=starts, order=order)


@st.composite
def dense_swarms(draw, max_robots: int):
    rng = np.random.default_rng(draw(st.integers(0, 2**31 - 1)))
    W = H = draw(st.integers(9, 14))
    free = rng.random((W, H)) >= draw(st.floats(0.0, 0.25))
    n = draw(st.integers(2, max_robots))
    assume(free.sum() > n + 1)
    start = clustered(rng, free, n)
    goal = np.argwhere(free)[rng.integers(free.sum())]
    order = draw(st.sampled_from(ORDERS))
    static = random_map_static(free, goal, start, draw(st.sampled_from(["geodesic", "euclidean"])), order)
    return free, static, start, draw(st.integers(1, n - 1)), order


@pytest.mark.parametrize("method", METHODS)
@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(data=st.data())
def test_every_method_is_safe_on_step_mrfs_with_overlapping_label_sets(method, data):
    free, static, pos, k, order = data.draw(dense_swarms(max_robots=3 if method in TINY_ONLY else 10))
    check_full_stencil_steps(method, free, static, pos, k, order, 1.0)


def check_full_stencil_steps(method: str, free: np.ndarray, static: np.ndarray, pos: np.ndarray, k: int, order: int,
                             downwash: float) -> None:
    """Three steps with every clear move a label: the method's own labelling is feasible and safe."""
    paths = [pos]
    for _ in range(3):
        labels = full_stencil_labels(free, pos, order)
        m = step_mrf(labels, graph_weights(pos, k), static, Morse(), 1.0, downwash)
        if method in TINY_ONLY:
            assume(np.prod(m.n_labels.astype(float)) <= MAX_LABELLINGS / 20)
        res = raw_result(m, method, mrf.Options(seed=0, max_iter=50))
        assert m.is_feasible(res.labels), f"{method} returned a labelling that breaks a conflict"
        pos = pos + labels.offsets[np.arange(len(pos)), res.labels]
        paths.append(pos)
    check_paths(np.stack(paths), free, downwash)


@st.composite
def dense_voxel_swarms(draw, max_robots: int):
    rng = np.random.default_rng(draw(st.integers(0, 2**31 - 1)))
    free = rng.random((7, 7, 6)) >= draw(st.floats(0.0, 0.2))
    downwash = draw(st.sampled_from([1.0, 2.0, 3.0]))
    n = draw(st.integers(2, max_robots))
    start = apart(clustered(rng, free, 3 * n), downwash)[:n]
    assume(len(start) >= 2)
    goal = np.argwhere(free)[rng.integers(free.sum())]
    order = draw(st.sampled_from([1, 2, 3]))
    static = random_map_static(free, goal, start, draw(st.sampled_from(["geodesic", "euclidean"])), order)
    return free, static, start, draw(st.integers(1, len(start) - 1)), order, downwash


@pytest.mark.parametrize("method", METHODS)
@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(data=st.data())
def test_every_method_is_safe_on_voxel_step_mrfs_with_overlapping_label_sets(method, data):
    free, static, pos, k, order, downwash = data.draw(dense_voxel_swarms(max_robots=3 if method in TINY_ONLY else 10))
    check_full_stencil_steps(method, free, static, pos, k, order, downwash)


@pytest.mark.parametrize("order", ORDERS)
def test_full_stencil_step_mrfs_are_full_of_binding_conflicts(order):
    # what the test above relies on: packed robots with overlapping label sets conflict a lot,
    # and an optimizer that ignored the conflicts would collide
    free = np.ones((14, 14), bool)
    start = clustered(np.random.default_rng(order), free, 10)
    goal = start[0]  # the cluster's centre: every robot wants the same few cells
    static = static_field(np.zeros(free.shape), goal, 1.0, GoalPotentialConfig(), ObstaclePotentialConfig())
    labels = full_stencil_labels(free, start, order)
    m = step_mrf(labels, graph_weights(start, 3), static, Morse(), 1.0)
    assert len(m.conflicts) >= len(start)
    x = mrf.minimize(without_conflicts(m), "icm").labels
    assert not m.is_feasible(x)
    assert brute_force_violations(np.stack([start, start + labels.offsets[np.arange(len(start)), x]]), free)


@pytest.mark.parametrize("order", [1, 2, 3])
def test_voxel_step_mrfs_have_binding_downwash_conflicts(order):
    # robots stacked two voxels apart (apart for c = 2) pulled to one cell: an optimizer that
    # ignored the conflicts would put robots in one another's downwash
    free = np.ones((8, 8, 9), bool)
    start = np.array([(x, y, z) for x in (3, 4) for y in (3, 4) for z in (2, 4, 6)])
    goal = np.array([3, 3, 4])
    static = static_field(np.zeros(free.shape), goal, 1.0, GoalPotentialConfig(), ObstaclePotentialConfig())
    labels = full_stencil_labels(free, start, order)
    m = step_mrf(labels, graph_weights(start, 3), static, Morse(), 1.0, 2.0)
    x = mrf.minimize(without_conflicts(m), "icm").labels
    assert not m.is_feasible(x)
    moved = np.stack([start, start + labels.offsets[np.arange(len(start)), x]])
    assert brute_force_violations(moved, free, downwash=2.0)
    safe = np.stack([start, start + labels.offsets[np.arange(len(start)), mrf.minimize(m, "icm").labels]])
    assert brute_force_violations(safe, free, downwash=2.0) == []
