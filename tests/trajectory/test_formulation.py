"""The CasADi formulation: compiled once per shape, exact cost, rows that mean what they say."""

import numpy as np
import pytest

import solvers.qp
from mrfswarm.trajectory import (
    Corridor,
    MinSnapProblem,
    MinSnapSolver,
    PolylineReference,
    corridor_sample_times,
    integral_squared_derivative,
    min_snap_qp,
    seam_jumps,
    tube_corridor,
)
from mrfswarm.trajectory.formulation import compiled_min_snap, hermite_basis
from mrfswarm.trajectory.polynomial import PiecewisePolynomial, derivative_row, tau_to_time
from solvers.errors import InvalidProblem
from support.trajectories import random_walk


def problem_with_everything(rng, degree=9, continuity=None):
    W = random_walk(rng, 4)
    T = rng.uniform(0.5, 2.0, 4)
    ref = PolylineReference(W, np.concatenate([[0.0], np.cumsum(T)]), law="smooth")
    return MinSnapProblem(W, T, degree=degree, continuity=continuity, start=[[0.2, 0.1], [0.0, -0.3]], end="free",
                          corridor=tube_corridor(ref, T, 5, 0.08))


def trajectory_of(problem, x):
    qp, norm = min_snap_qp(problem)
    c = norm.tau_coefficients(problem, x)
    return PiecewisePolynomial(problem.durations, tau_to_time(c, problem.durations))


def test_compiled_once_per_shape_with_a_fixed_pattern():
    rng = np.random.default_rng(0)
    p1 = problem_with_everything(rng)
    p2 = problem_with_everything(rng)
    assert p1.shape == p2.shape
    assert compiled_min_snap(p1.shape) is compiled_min_snap(p2.shape)
    q1, _ = min_snap_qp(p1)
    q2, _ = min_snap_qp(p2)
    for a, b in ((q1.P, q2.P), (q1.A, q2.A)):
        np.testing.assert_array_equal(a.indptr, b.indptr)
        np.testing.assert_array_equal(a.indices, b.indices)
    assert not np.allclose(q1.A.data, q2.A.data)  # the data did change
    other = MinSnapProblem(p1.waypoints, p1.durations, degree=7)
    assert compiled_min_snap(other.shape) is not compiled_min_snap(p1.shape)


def test_hermite_basis_interpolates_end_derivatives():
    for D, q in ((7, 4), (9, 4), (5, 3)):
        herm, bub = hermite_basis(D, q)
        for r in range(q):
            for end, tau in ((0, 0.0), (1, 1.0)):
                row = derivative_row(D, r, tau)
                expect = np.zeros(2 * q)
                expect[end * q + r] = 1.0
                np.testing.assert_allclose(row @ herm, expect, atol=1e-10)
                np.testing.assert_allclose(row @ bub, 0.0, atol=1e-12)
        assert np.linalg.matrix_rank(np.hstack([herm, bub])) == D + 1  # a basis of degree-D polynomials


def test_qp_objective_is_the_exact_snap_integral():
    # any x (feasible or not): x'Px/2 in normalized units is the integral of |sigma''''|^2
    rng = np.random.default_rng(1)
    p = problem_with_everything(rng)
    qp, norm = min_snap_qp(p)
    for _ in range(5):
        x = rng.normal(size=qp.n)
        traj = trajectory_of(p, x)
        J = qp.objective(x) * norm.scale**2 * norm.time_scale ** (1 - 2 * 4)
        assert J == pytest.approx(integral_squared_derivative(traj, 4), rel=1e-9)


def test_constraint_rows_are_positions_derivatives_and_corridor_samples():
    rng = np.random.default_rng(2)
    p = problem_with_everything(rng)
    qp, norm = min_snap_qp(p)
    x = rng.normal(size=qp.n)
    traj = trajectory_of(p, x)
    ax = qp.A @ x
    M, K, dim = 4, 5, 2
    per_dim = qp.m // dim
    for d in range(dim):
        rows = ax[d * per_dim:(d + 1) * per_dim]
        np.testing.assert_allclose(rows[: M + 1] * norm.scale + norm.center[d], traj(traj.knots)[:, d], atol=1e-9)
        g = rows[M + 1:M + 3] * norm.scale / norm.time_scale ** np.arange(1, 3)
        np.testing.assert_allclose(g, [traj(0.0, 1)[d], traj(0.0, 2)[d]], rtol=1e-9, atol=1e-9)
        samples = rows[-M * K:] * norm.scale + norm.center[d]
        np.testing.assert_allclose(samples, traj(corridor_sample_times(p.durations, K))[..., d].ravel(), atol=1e-9)
    # and the knot derivatives up to q-1 are shared: continuity by construction, for any x
    assert np.abs(seam_jumps(traj, 3)).max() < 1e-8 * np.abs(traj.coefficients).max()


@pytest.mark.parametrize("name", solvers.qp.BACKENDS.available(lambda c: c.inequalities), ids=str)
def test_continuity_above_q_minus_1_is_enforced_under_a_corridor(name):
    rng = np.random.default_rng(3)
    p4 = problem_with_everything(rng, degree=9, continuity=5)
    p3 = MinSnapProblem(p4.waypoints, p4.durations, degree=9, start=p4.start, end="free", corridor=p4.corridor)
    r4 = MinSnapSolver(name).solve(p4)
    r3 = MinSnapSolver(name).solve(p3)
    scale = np.abs(r4.trajectory.coefficients).max()
    assert np.abs(seam_jumps(r4.trajectory, 5)).max() < 1e-6 * scale
    assert np.abs(seam_jumps(r3.trajectory, 5)[:, 4:]).max() > 1e-3 * scale  # c = 3 leaves snap free to jump
    assert r4.cost >= r3.cost * (1 - 1e-9)
    assert p4.corridor.violation(r4.trajectory) < 1e-6


def test_problem_validation_messages():
    W = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 1.0]])
    with pytest.raises(InvalidProblem, match="2 pieces"):
        MinSnapProblem(W, [1.0])
    with pytest.raises(InvalidProblem, match="duration 1"):
        MinSnapProblem(W, [1.0, -1.0])
    with pytest.raises(InvalidProblem, match="waypoint 1 is not finite"):
        MinSnapProblem([[0, 0], [np.nan, 0]], [1.0])
    with pytest.raises(InvalidProblem, match="degree >= 2q - 1 = 7"):
        MinSnapProblem(W, [1.0, 1.0], degree=6)
    with pytest.raises(InvalidProblem, match="continuity"):
        MinSnapProblem(W, [1.0, 1.0], continuity=1)
    with pytest.raises(InvalidProblem, match="at most q - 1 = 3"):
        MinSnapProblem(W, [1.0, 1.0], start=np.zeros((4, 2)))
    with pytest.raises(InvalidProblem, match="'rest', 'free'"):
        MinSnapProblem(W, [1.0, 1.0], end="stop")
    with pytest.raises(InvalidProblem, match="corridor has 1 pieces"):
        MinSnapProblem(W, [1.0, 1.0], corridor=Corridor(np.zeros((1, 2, 2)), np.ones((1, 2, 2))))
