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
    assert p.with_data(durations=2 * T).waypoint_tolerance is not None
