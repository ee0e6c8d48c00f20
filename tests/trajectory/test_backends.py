"""Every registered QP backend on the formulated min-snap QP: against the closed form and each other."""

import numpy as np
import pytest

import solvers.qp
from mrfswarm.trajectory import (
    CLOSED_FORM,
    MinSnapProblem,
    MinSnapSolver,
    min_snap_qp,
    segment_reference,
    solve_banded,
    solve_min_snap,
    tube_corridor,
)
from mrfswarm.trajectory.polynomial import PiecewisePolynomial, tau_to_time
from solvers.errors import InfeasibleError, InvalidProblem
from support.trajectories import random_walk

NAMES = solvers.qp.BACKENDS.names()


def backend_or_skip(name, need_inequalities=False):
    b = solvers.qp.BACKENDS.get(name) if name in solvers.qp.available() else None
    if b is None:
        pytest.skip(f"{name} not installed")
    if need_inequalities and not b.capabilities.inequalities:
        pytest.skip(f"{name} solves equality-only problems")
    return b


def reference_problems():
    rng = np.random.default_rng(42)
    W2 = random_walk(rng, 8)
    W3 = random_walk(rng, 5, 3)
    return {
        "2d_rest": MinSnapProblem(W2, rng.uniform(0.5, 2.0, 8)),
        "3d_given_start_free_end": MinSnapProblem(W3, rng.uniform(0.5, 2.0, 5),
                                                  start=[[0.4, 0.0, -0.2], [0.0, 0.5, 0.0]], end="free"),
        "2d_min_jerk": MinSnapProblem(W2, np.full(8, 0.8), degree=5, derivative=3),
        "2d_degree_9": MinSnapProblem(W2[:5], rng.uniform(0.5, 2.0, 4), degree=9),
        "2d_short_pieces": MinSnapProblem(W2, np.full(8, 0.1)),
        "2d_long_pieces": MinSnapProblem(W2, np.full(8, 20.0)),
    }


def closed_form_reference(problem):
    """Banded closed form; degree > 2q-1 has the same optimum as degree 2q-1 (padded)."""
    q = problem.derivative
    p = MinSnapProblem(problem.waypoints, problem.durations, degree=2 * q - 1, derivative=q,
                       start=problem.start, end=problem.end)
    sol = solve_banded(p)
    return PiecewisePolynomial(p.durations, tau_to_time(sol.coefficients, p.durations)), sol.cost


@pytest.mark.parametrize("name", NAMES, ids=str)
@pytest.mark.parametrize("case", list(reference_problems()), ids=str)
def test_backend_matches_closed_form(name, case):
    backend_or_skip(name)
    problem = reference_problems()[case]
    ref, ref_cost = closed_form_reference(problem)
    res = MinSnapSolver(name, formulated=True).solve(problem)
    assert res.method == "qp" and res.backend == name
    assert res.cost == pytest.approx(ref_cost, rel=1e-6)
    t = np.linspace(0, ref.duration, 1000)
    np.testing.assert_allclose(res.trajectory(t), ref(t), atol=1e-5)


def corridor_problem():
    """An L-shaped path; a tube around a rest-to-rest motion along it binds the min-snap trajectory.

    Feasible by construction: the reference itself (the one-piece min-snap law on every
    segment) is a degree-7 trajectory that is C^3 at the knots.
    """
    W = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [2.0, 1.0], [2.0, 2.0]])
    T = np.ones(4)
    times = np.arange(5.0)
    from mrfswarm.trajectory import PolylineReference

    ref = PolylineReference(W, times, law="smooth")
    return MinSnapProblem(W, T, corridor=tube_corridor(ref, T, 6, 0.1))


def check_kkt(qp, x, tol=1e-5):
    """Independent optimality check: stationarity with multipliers of the right signs on tight rows."""
    ax = qp.A @ x
    scale = max(1.0, np.abs(ax).max())
    at_lo = ax <= qp.l + 1e-7 * scale
    at_hi = ax >= qp.u - 1e-7 * scale
    active = at_lo | at_hi
    Aa = qp.A[active].toarray()
    g = qp.P @ x
    y, *_ = np.linalg.lstsq(Aa.T, -g, rcond=None)
    assert np.linalg.norm(Aa.T @ y + g) <= tol * max(1.0, np.linalg.norm(g))
    eq = (qp.l == qp.u)[active]
    lo_only = (at_lo & ~at_hi)[active] & ~eq
    hi_only = (at_hi & ~at_lo)[active] & ~eq
    ymax = max(1.0, np.abs(y).max())
    assert np.all(y[lo_only] <= tol * ymax) and np.all(y[hi_only] >= -tol * ymax)
    return int(np.count_nonzero(active & ~(qp.l == qp.u)))


@pytest.mark.parametrize("name", NAMES, ids=str)
def test_corridor_active_and_optimal(name):
    backend_or_skip(name, need_inequalities=True)
    problem = corridor_problem()
    res = MinSnapSolver(name).solve(problem)
    free = solve_min_snap(problem.waypoints, problem.durations)
    assert res.cost > 1.01 * free.cost  # the corridor changes the optimum
    assert problem.corridor.violation(free.trajectory) > 0.01
    assert problem.corridor.violation(res.trajectory) < 1e-6
    np.testing.assert_allclose(res.trajectory(res.trajectory.knots), problem.waypoints, atol=1e-6)
    qp, norm = min_snap_qp(problem)
    tight = check_kkt(qp, res.solution.x)
    assert tight >= 1  # some corridor rows are active at the optimum


def test_qp_backends_agree_with_each_other_under_a_corridor():
    names = solvers.qp.BACKENDS.available(lambda c: c.inequalities)
    if not names:
        pytest.skip("no QP backend with inequalities installed")
    problem = corridor_problem()
    results = {n: MinSnapSolver(n).solve(problem) for n in names}
    base = results[names[0]]
    t = np.linspace(0, base.trajectory.duration, 1000)
    for n, r in results.items():
        assert r.cost == pytest.approx(base.cost, rel=1e-6), n
        np.testing.assert_allclose(r.trajectory(t), base.trajectory(t), atol=1e-5, err_msg=n)


@pytest.mark.parametrize("name", NAMES, ids=str)
def test_warm_resolve_after_new_waypoints(name):
    backend_or_skip(name)
    rng = np.random.default_rng(5)
    W = random_walk(rng, 6)
    T = np.ones(6)
    solver = MinSnapSolver(name, formulated=True)
    solver.solve(MinSnapProblem(W, T))
    W2 = W + rng.normal(scale=0.2, size=W.shape)
    again = solver.solve(MinSnapProblem(W2, T))
    fresh = solve_min_snap(W2, T)
    assert again.cost == pytest.approx(fresh.cost, rel=1e-6)
    t = np.linspace(0, 6, 300)
    np.testing.assert_allclose(again.trajectory(t), fresh.trajectory(t), atol=1e-5)


def test_closed_form_with_corridor_is_a_clear_error():
    with pytest.raises(InvalidProblem, match="corridor constraints and waypoint tolerances need a QP backend"):
        MinSnapSolver(CLOSED_FORM).solve(corridor_problem())


def test_default_backend_routes():
    p = corridor_problem()
    res = MinSnapSolver().solve(p)
    assert res.backend == solvers.qp.DEFAULT_BACKEND and res.method == "qp"
    free = MinSnapProblem(p.waypoints, p.durations)
    res = MinSnapSolver().solve(free)
    assert res.backend == CLOSED_FORM and res.method == "banded"


def test_infeasible_corridor_raises():
    W = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]])
    T = np.ones(2)
    # a tube around a reference that is far from the waypoints mid-piece
    ref = segment_reference([0.0, 5.0], [2.0, 5.0], 0.0, 2.0)
    p = MinSnapProblem(W, T, corridor=tube_corridor(ref, T, 3, 0.1))
    with pytest.raises(InfeasibleError):
        MinSnapSolver(solvers.qp.DEFAULT_BACKEND).solve(p)


# 1000 pieces is 8000 variables: the default backend and the registry's generic closed form
# (sparse KKT) here; every other backend is checked on the small reference problems above.
# (Measured when the QP backends landed: piqp, proxsuite, cvxpy and ipopt pass this test in
# 0.01-3 s; casadi's qpOASES is a dense active-set method: 4.9 s at 100 pieces, minutes at 1000.)
@pytest.mark.parametrize("name", [solvers.qp.DEFAULT_BACKEND, CLOSED_FORM], ids=str)
def test_thousand_pieces_qp_path(name):
    backend_or_skip(name)
    rng = np.random.default_rng(1000)
    W = random_walk(rng, 1000)
    T = rng.uniform(0.8, 1.25, 1000)
    problem = MinSnapProblem(W, T)
    ref, ref_cost = closed_form_reference(problem)
    res = MinSnapSolver(name, formulated=True).solve(problem)
    assert res.cost == pytest.approx(ref_cost, rel=1e-6)
    t = np.linspace(0, ref.duration, 20000)
    np.testing.assert_allclose(res.trajectory(t), ref(t), atol=1e-5)
