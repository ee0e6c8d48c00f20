"""The discrete stage: invariants on random maps and swarms, monotone steps, convergence."""

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mrfswarm.discrete.planner import DiscreteProblem, mrf_step, plan_discrete
from mrfswarm.discrete.potentials import Morse
from mrfswarm.discrete.safety import discrete_violations
from solvers.errors import SolverNotFound
from support.fields import random_map_static


def brute_invariants(paths, free):
    """An independent check by dense sampling (not the planner's own geometry)."""
    W, H = free.shape
    for t in range(len(paths)):
        p = paths[t]
        assert len({tuple(c) for c in p.tolist()}) == len(p), f"shared cell at step {t}"
        assert np.all((p >= 0) & (p < [W, H])), f"off the map at step {t}"
        assert free[p[:, 0], p[:, 1]].all(), f"robot in an obstacle at step {t}"
        if t == 0:
            continue
        s = np.linspace(0, 1, 401)[:, None, None]
        pos = paths[t - 1][None] + s * (p - paths[t - 1])[None]  # (S, N, 2)
        d = np.hypot(*(pos[:, :, None, :] - pos[:, None, :, :]).transpose(3, 0, 1, 2))
        iu = np.triu_indices(len(p), 1)
        assert d[:, iu[0], iu[1]].min() >= 1 - 1e-3, f"robots closer than one cell during step {t}"
        # every sampled point of every move lies in a free cell (the 0.5-cell clearance is stricter)
        cells = np.floor(pos + 0.5).astype(int).reshape(-1, 2)
        assert free[cells[:, 0], cells[:, 1]].all(), f"a move crosses an obstacle during step {t}"


@st.composite
def scenarios(draw):
    seed = draw(st.integers(0, 2**31 - 1))
    rng = np.random.default_rng(seed)
    W, H = draw(st.integers(8, 24)), draw(st.integers(8, 24))
    free = rng.random((W, H)) > draw(st.floats(0.0, 0.35))
    cells = np.argwhere(free)
    n = draw(st.integers(2, min(14, len(cells))))
    rng.shuffle(cells)
    start = cells[:n]
    k = draw(st.integers(1, n - 1))
    order = draw(st.sampled_from([1, 2, 4, 5, 8]))
    goal = cells[n] if len(cells) > n and draw(st.booleans()) else None
    static = random_map_static(free, goal, start, draw(st.sampled_from(["geodesic", "euclidean"])), order)
    return DiscreteProblem(free=free, static=static, start=start, goal=goal, morse=Morse(), k=k, order=order,
                           trim_backward=draw(st.booleans()))


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(scenarios(), st.sampled_from(["icm"]))
def test_invariants_hold_on_random_maps(problem, method):
    plan = plan_discrete(problem, method=method, max_steps=8)
    brute_invariants(plan.paths, problem.free)
    assert discrete_violations(plan.paths, problem.free) == []


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(scenarios())
def test_each_step_never_increases_the_energy_it_minimizes(problem):
    pos = problem.start
    for _ in range(4):
        out = mrf_step(problem, pos)
        assert out.energy_after <= out.energy_before + 1e-9
        pos = out.positions


def test_discrete_violations_catch_each_kind():
    free = np.ones((6, 6), bool)
    free[3, 3] = False
    ok = np.array([[[0, 0], [2, 0]], [[1, 0], [3, 0]]])
    assert discrete_violations(ok, free) == []
    swap = np.array([[[0, 0], [1, 0]], [[1, 1], [0, 1]]])
    assert any("close while moving" in v for v in discrete_violations(swap, free))
    shared = np.array([[[0, 0], [1, 1]], [[1, 1], [1, 1]]])
    assert any("share" in v for v in discrete_violations(shared, free))
    wall = np.array([[[3, 3], [0, 0]]])
    assert any("occupied" in v for v in discrete_violations(wall, free))
    # the move (2,2) -> (3,4) passes through (2.5, 3), on the edge of the blocked square (3, 3)
    corner = np.array([[[2, 2], [0, 5]], [[3, 4], [0, 5]]])
    assert any("cuts an obstacle" in v for v in discrete_violations(corner, free))
    off = np.array([[[0, 0], [6, 0]]])
    assert any("off the map" in v for v in discrete_violations(off, free))


def test_free_space_five_robots_form_a_pentagon():
    """The paper's Fig. 6a: 5 robots, k = 3, no static field: a few steps to near-equal spacing."""
    free = np.ones((30, 30), bool)
    start = np.array([[14, 14], [15, 15], [16, 14], [14, 16], [15, 13]])
    problem = DiscreteProblem(free=free, static=np.zeros((30, 30)), start=start, goal=None, morse=Morse(), k=3, order=2)
    plan = plan_discrete(problem, max_steps=50)
    assert plan.converged and plan.n_steps <= 12
    final = plan.paths[-1].astype(float)
    D = np.hypot(*(final[:, None] - final[None]).transpose(2, 0, 1))
    np.fill_diagonal(D, np.inf)
    nn = D.min(axis=1)
    assert nn.max() / nn.min() < 1.1  # near-equal nearest-neighbour distances
    # and a convex pentagon: every robot is a vertex of the convex hull
    from scipy.spatial import ConvexHull
    assert len(ConvexHull(final).vertices) == 5


def test_icm_matches_exact_for_one_free_robot():
    free = np.ones((12, 12), bool)
    static = np.random.default_rng(0).random((12, 12))
    for start in ([[5, 5], [9, 2]], [[1, 1], [10, 10]]):
        problem = DiscreteProblem(free=free, static=static, start=np.array(start), goal=None, morse=Morse(), k=1, order=4)
        a = mrf_step(problem, problem.start, "icm")
        b = mrf_step(problem, problem.start, "exact")
        assert a.energy_after == pytest.approx(b.energy_after)


def test_mrf_step_uses_the_registry():
    free = np.ones((8, 8), bool)
    problem = DiscreteProblem(free=free, static=np.zeros((8, 8)), start=np.array([[1, 1], [4, 4]]), goal=None,
                              morse=Morse(), k=1)
    with pytest.raises(SolverNotFound, match="unknown MRF method 'nope'"):
        mrf_step(problem, problem.start, "nope")


def test_an_optimizer_that_refuses_a_step_is_said_with_the_step():
    """A method over its own limit (exact: 5e6 labellings) refuses one step; the error says which step of which
    plan (a tour's refusal came after 27 s of planning without it)."""
    from mrfswarm.discrete.goal_distance import goal_distance
    from solvers.mrf import InvalidProblem

    free = np.ones((12, 12), dtype=bool)
    goal = np.array([11, 11])
    d = goal_distance(free, goal)
    static = 3.0 * np.exp(d.path / 20.0)
    start = np.array([[2 * i, 0] for i in range(6)] + [[2 * i, 2] for i in range(6)])  # 12 robots, 9 labels each
    problem = DiscreteProblem(free=free, static=static, start=start, goal=goal, morse=Morse(), k=3, order=2,
                              contested="shared", goal_distance=d.path, goal_path=d.path, goal_region_radius=3.0)
    with pytest.raises(InvalidProblem,
                       match=r"^MRF step 1 \(contested = 'shared'\): exact: about 1\.1e10 labellings exceed"):
        plan_discrete(problem, method="exact", max_steps=5)


@pytest.mark.parametrize("tol", [float("inf"), float("nan"), 1.0, -1e-3])
def test_plan_discrete_refuses_a_tolerance_outside_its_range(tol):
    """mrf.tol's range, [0, 1), held for configs only: plan_discrete(tol=inf) ended after one step, "trapped",
    and NaN after none, "stalled"."""
    free = np.ones((8, 6), bool)
    start, goal = np.array([[0, 1], [0, 3]]), np.array([7, 2])
    problem = DiscreteProblem(free=free, static=random_map_static(free, goal, start, "geodesic", 2), start=start,
                              goal=goal, morse=Morse(), k=1, order=2)
    with pytest.raises(ValueError, match=rf"^tol = {tol!r}: must be in \[0, 1\)"):
        plan_discrete(problem, tol=tol)
    assert len(plan_discrete(problem, tol=0.0, max_steps=30).paths) > 2
