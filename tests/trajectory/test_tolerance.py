"""Waypoint tolerances: knots may move within a box (what waypoint pruning frees)."""

import numpy as np
import pytest

import solvers
from mrfswarm.trajectory import CLOSED_FORM, MinSnapProblem, MinSnapSolver, solve_min_snap
from solvers.errors import InvalidProblem

W = np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 0.0], [3.0, 1.0], [4.0, 0.0]])
T = np.ones(4)


def test_zero_tolerance_is_the_exact_problem():
    exact = solve_min_snap(W, T, backend="osqp")
    same = MinSnapSolver("osqp").solve(MinSnapProblem(W, T, waypoint_tolerance=np.zeros(5)))
    assert same.cost == pytest.approx(exact.cost, rel=1e-6)


@pytest.mark.parametrize("backend", [b for b in solvers.qp.available() if b != CLOSED_FORM])
def test_tolerance_lets_knots_move_within_their_box_and_lowers_the_cost(backend):
    tol = np.array([0.0, 0.3, 0.3, 0.3, 0.0])
    exact = solve_min_snap(W, T, backend=backend)
    res = MinSnapSolver(backend).solve(MinSnapProblem(W, T, waypoint_tolerance=tol))
    knots = res.trajectory.evaluate(np.arange(5.0))
    dev = np.abs(knots - W)
    assert np.all(dev <= tol[:, None] + 1e-5)
    np.testing.assert_allclose(knots[[0, -1]], W[[0, -1]], atol=1e-6)
    assert res.cost < 0.5 * exact.cost  # the zig-zag flattens a lot
    assert np.any(np.isclose(dev[1:-1], 0.3, atol=1e-4))  # some box is active


def test_tolerance_validation_and_routing():
    with pytest.raises(InvalidProblem, match="waypoint_tolerance must have shape"):
        MinSnapProblem(W, T, waypoint_tolerance=np.zeros(4))
    with pytest.raises(InvalidProblem, match=">= 0"):
        MinSnapProblem(W, T, waypoint_tolerance=-np.ones(5))
    with pytest.raises(InvalidProblem, match="need a QP backend"):
        MinSnapSolver(CLOSED_FORM).solve(MinSnapProblem(W, T, waypoint_tolerance=np.full(5, 0.1)))
    p = MinSnapProblem(W, T, waypoint_tolerance=np.full(5, 0.1))
    np.testing.assert_array_equal(p.with_data(durations=2 * T).waypoint_tolerance, np.full((5, 2), 0.1))  # kept, per axis


@pytest.mark.parametrize("backend", [b for b in ("osqp", "piqp") if b in solvers.qp.available()])
def test_batch_equals_separate_solves(backend):
    from mrfswarm.trajectory import MinSnapBatchSolver, PolylineReference, tube_corridor

    rng = np.random.default_rng(7)
    problems = []
    for _ in range(6):
        Wk = np.cumsum(rng.normal(size=(4, 2)), axis=0) * rng.uniform(0.5, 3)
        Tk = np.array([1.0, 1.5, 0.8])
        ref = PolylineReference(Wk, np.concatenate(([0.0], np.cumsum(Tk))), law="smooth")
        problems.append(MinSnapProblem(Wk, Tk, corridor=tube_corridor(ref, Tk, 5, 0.3),
                                       waypoint_tolerance=np.array([0.0, 0.2, 0.2, 0.0]),
                                       start=0.1 * rng.normal(size=(3, 2))))
    batch = MinSnapBatchSolver(backend)
    for _ in range(2):  # the second call reuses the prepared backend (update + warm start)
        got = batch.solve(problems)
    t = np.linspace(0, 3.3, 200)
    for p, g in zip(problems, got):
        ref = MinSnapSolver(backend).solve(p).trajectory
        np.testing.assert_allclose(g.evaluate(t), ref.evaluate(t), atol=2e-4)
        assert p.corridor.violation(g) < 1e-5
    with pytest.raises(InvalidProblem, match="one shape"):
        batch.solve([problems[0], MinSnapProblem(W, T)])
