"""The banded closed form: known answers, optimality conditions, scale laws, accuracy."""

import numpy as np
import pytest

from mrfswarm.trajectory import (
    MinSnapProblem,
    integral_squared_derivative,
    seam_jumps,
    solve_banded,
    solve_min_snap,
)
from solvers.errors import InvalidProblem
from support.trajectories import exact_banded_coefficients, kkt_trajectory, random_walk


def test_one_piece_min_snap_is_the_septic_smoothstep():
    # rest to rest from 0 to 1 in 1 s: 35 t^4 - 84 t^5 + 70 t^6 - 20 t^7, snap cost 100800
    res = solve_min_snap([[0.0], [1.0]], [1.0])
    np.testing.assert_allclose(res.trajectory.coefficients[0, :, 0], [0, 0, 0, 0, 35, -84, 70, -20], atol=1e-9)
    assert res.cost == pytest.approx(100800.0, rel=1e-12)


def test_one_piece_min_jerk_is_the_classic_quintic():
    res = solve_min_snap([[0.0], [1.0]], [1.0], degree=5, derivative=3)
    np.testing.assert_allclose(res.trajectory.coefficients[0, :, 0], [0, 0, 0, 10, -15, 6], atol=1e-10)
    assert res.cost == pytest.approx(720.0, rel=1e-12)  # int (60 - 360 t + 360 t^2)^2 dt


def test_one_piece_scaled_in_space_and_time():
    # from a to b in T: a + (b - a) s(t / T), cost |b - a|^2 100800 / T^7
    a, b, T = np.array([1.0, -2.0, 0.5]), np.array([4.0, 2.0, 0.5]), 2.5
    res = solve_min_snap([a, b], [T])
    t = np.linspace(0, T, 50)
    tau = t / T
    s = 35 * tau**4 - 84 * tau**5 + 70 * tau**6 - 20 * tau**7
    np.testing.assert_allclose(res.trajectory(t), a + s[:, None] * (b - a), atol=1e-12)
    assert res.cost == pytest.approx(np.sum((b - a) ** 2) * 100800 / T**7, rel=1e-11)


@pytest.mark.parametrize("dim", [2, 3])
def test_passes_waypoints_is_continuous_and_at_rest(dim):
    rng = np.random.default_rng(dim)
    W = random_walk(rng, 12, dim)
    T = rng.uniform(0.5, 2.0, 12)
    traj = solve_min_snap(W, T).trajectory
    np.testing.assert_allclose(traj(traj.knots), W, atol=1e-10)
    jumps = seam_jumps(traj, 6)  # the optimum is C^(2q-2) = C^6
    scale = np.abs(traj.coefficients).max()
    assert np.abs(jumps).max() < 1e-9 * scale
    for r in (1, 2, 3):
        assert np.abs(traj([0.0, traj.duration], r)).max() < 1e-9
    assert np.abs(traj(traj.duration / 2, 1)).max() > 1e-3  # not trivially at rest everywhere


def test_given_and_free_ends():
    rng = np.random.default_rng(7)
    W = random_walk(rng, 5)
    T = np.full(5, 1.2)
    start = np.array([[0.5, -0.2], [0.1, 0.3], [0.0, 1.0]])  # velocity, acceleration, jerk
    traj = solve_min_snap(W, T, start=start, end="free").trajectory
    for r in (1, 2, 3):
        np.testing.assert_allclose(traj(0.0, r), start[r - 1], atol=1e-9)
    # a free end meets the natural conditions: derivatives q..2q-2 vanish there
    for r in (4, 5, 6):
        assert np.abs(traj(traj.duration, r)).max() < 1e-7 * np.abs(traj.coefficients).max()
    # only a velocity given at the end: derivatives 2 and 3 free, so 5 and 4 vanish
    traj = solve_min_snap(W, T, end=[1.0, 0.0]).trajectory
    np.testing.assert_allclose(traj(traj.duration, 1), [1.0, 0.0], atol=1e-9)
    for r in (4, 5):
        assert np.abs(traj(traj.duration, r)).max() < 1e-7 * np.abs(traj.coefficients).max()


def test_closed_form_is_optimal_against_feasible_perturbations():
    # the formulated QP (degree 9, a larger space with the same optimum): every feasible
    # direction around the closed-form solution raises the objective
    import scipy.linalg as sla

    from mrfswarm.trajectory import min_snap_qp

    rng = np.random.default_rng(11)
    W = random_walk(rng, 4)
    T = rng.uniform(0.7, 1.5, 4)
    res = solve_min_snap(W, T)
    p = MinSnapProblem(W, T, degree=9)
    qp, norm = min_snap_qp(p)
    A = qp.A.toarray()
    xs = np.linalg.solve(np.block([[qp.P.toarray(), A.T], [A, np.zeros((qp.m, qp.m))]]),
                         np.concatenate([np.zeros(qp.n), qp.l]))[: qp.n]
    # xs is the closed form's trajectory
    c = norm.tau_coefficients(p, xs)
    np.testing.assert_allclose(c[:, :8, :], res.trajectory.tau_coefficients(), atol=1e-8)
    N = sla.null_space(A)
    f0 = qp.objective(xs)
    for _ in range(20):
        d = N @ rng.normal(size=N.shape[1])
        assert qp.objective(xs + 1e-3 * d) > f0
    # and the QP objective is the snap integral, in normalized units
    assert f0 * norm.scale**2 * norm.time_scale ** (1 - 2 * 4) == pytest.approx(res.cost, rel=1e-8)


def test_higher_degree_has_the_same_optimum():
    # the optimum over degree >= 2q-1 is piecewise degree 2q-1 (Euler-Lagrange: sigma^(2q) = 0)
    rng = np.random.default_rng(5)
    W = random_walk(rng, 7, 3)
    T = rng.uniform(0.5, 2.0, 7)
    ref = solve_min_snap(W, T)
    traj9 = kkt_trajectory(MinSnapProblem(W, T, degree=9))
    t = np.linspace(0, ref.trajectory.duration, 500)
    np.testing.assert_allclose(traj9(t), ref.trajectory(t), atol=1e-8)
    assert integral_squared_derivative(traj9, 4) == pytest.approx(ref.cost, rel=1e-8)
    np.testing.assert_allclose(traj9.coefficients[:, 8:, :], 0.0, atol=1e-6 * np.abs(traj9.coefficients).max())


@pytest.mark.parametrize("q", [2, 3, 4, 5])
def test_cost_scaling_law(q):
    # rest to rest: J(alpha T) = alpha^(1 - 2q) J(T); space scaling: J(beta W) = beta^2 J(W)
    rng = np.random.default_rng(q)
    W = random_walk(rng, 6)
    T = rng.uniform(0.5, 2.0, 6)
    J = solve_min_snap(W, T, degree=2 * q - 1, derivative=q).cost
    for alpha in (0.1, 0.5, 3.0, 20.0):
        Ja = solve_min_snap(W, alpha * T, degree=2 * q - 1, derivative=q).cost
        assert Ja == pytest.approx(alpha ** (1 - 2 * q) * J, rel=1e-9)
    assert solve_min_snap(3.0 * W + 7.0, T, degree=2 * q - 1, derivative=q).cost == pytest.approx(9 * J, rel=1e-9)


def test_uniform_scaling_keeps_the_shape():
    rng = np.random.default_rng(8)
    W = random_walk(rng, 5)
    T = rng.uniform(0.5, 2.0, 5)
    a = solve_min_snap(W, T).trajectory
    b = solve_min_snap(W, 2.5 * T).trajectory
    t = np.linspace(0, a.duration, 200)
    np.testing.assert_allclose(b(2.5 * t), a(t), atol=1e-10)
    np.testing.assert_allclose(b.coefficients, a.time_scaled(2.5).coefficients, atol=1e-9)


@pytest.mark.parametrize("duration", [0.1, 1.0, 20.0])
def test_thousand_pieces_accurate(duration):
    rng = np.random.default_rng(1000)
    W = random_walk(rng, 1000)
    T = np.full(1000, duration)
    res = solve_min_snap(W, T)
    traj = res.trajectory
    np.testing.assert_allclose(traj(traj.knots), W, atol=1e-9)
    jumps = np.abs(seam_jumps(traj, 6)).max(axis=(0, 2)) * duration ** np.arange(7)  # in units of position
    assert jumps.max() < 1e-8 * np.abs(W).max()
    ref = kkt_trajectory(MinSnapProblem(W, T))
    t = np.linspace(0, traj.duration, 20000)
    np.testing.assert_allclose(traj(t), ref(t), atol=1e-7)
    assert integral_squared_derivative(ref, 4) == pytest.approx(res.cost, rel=1e-9)


def test_mixed_short_and_long_pieces_against_exact_arithmetic():
    # durations from 0.1 s to 20 s in one problem: T^(1-2q) spans 16 decades
    W = np.array([[0.0, 0.0], [0.3, 0.1], [5.0, 4.0], [5.2, 4.1], [9.0, -3.0]])
    T = np.array([0.1, 20.0, 0.1, 7.0])
    p = MinSnapProblem(W, T)
    exact = exact_banded_coefficients(p)
    got = solve_banded(p).coefficients
    np.testing.assert_allclose(got, exact, rtol=0, atol=1e-9 * np.abs(exact).max())


def test_gradient_matches_finite_differences():
    rng = np.random.default_rng(21)
    W = random_walk(rng, 6, 3)
    T = rng.uniform(0.5, 2.0, 6)
    for kw in ({}, {"start": "free"}, {"end": [[0.3, -0.2, 0.1]]}, {"start": np.ones((3, 3)) * 0.2, "end": "free"}):
        p = MinSnapProblem(W, T, **kw)
        g = solve_banded(p, gradient=True).gradient
        fd = np.zeros_like(T)
        for j in range(T.size):
            h = 1e-5 * T[j]
            Tp, Tm = T.copy(), T.copy()
            Tp[j] += h
            Tm[j] -= h
            fd[j] = (solve_banded(p.with_data(durations=Tp)).cost - solve_banded(p.with_data(durations=Tm)).cost) / (2 * h)
        np.testing.assert_allclose(g, fd, rtol=1e-6, atol=1e-8 * np.abs(fd).max())


def test_gradient_obeys_euler_homogeneity():
    # J(alpha T) = alpha^(1-2q) J(T)  =>  T . dJ/dT = (1 - 2q) J
    rng = np.random.default_rng(22)
    W = random_walk(rng, 9)
    p = MinSnapProblem(W, rng.uniform(0.3, 3.0, 9))
    sol = solve_banded(p, gradient=True)
    assert p.durations @ sol.gradient == pytest.approx(-7 * sol.cost, rel=1e-10)


def test_banded_refuses_corridors_and_higher_degree():
    from mrfswarm.trajectory import Corridor

    W = np.array([[0.0, 0.0], [1.0, 0.0]])
    with pytest.raises(InvalidProblem, match="2q - 1"):
        solve_banded(MinSnapProblem(W, [1.0], degree=9))
    c = Corridor(np.full((1, 2, 2), -5.0), np.full((1, 2, 2), 5.0))
    with pytest.raises(InvalidProblem, match="corridor"):
        solve_banded(MinSnapProblem(W, [1.0], corridor=c))


def test_continuity_above_q_minus_1_changes_nothing_without_corridor():
    rng = np.random.default_rng(9)
    W = random_walk(rng, 5)
    T = rng.uniform(0.5, 2.0, 5)
    a = solve_min_snap(W, T).trajectory
    b = solve_min_snap(W, T, continuity=6).trajectory
    np.testing.assert_allclose(a.coefficients, b.coefficients, atol=1e-12)
    ref = kkt_trajectory(MinSnapProblem(W, T, continuity=6))
    np.testing.assert_allclose(ref.coefficients, a.coefficients, atol=1e-7 * np.abs(a.coefficients).max())


def test_min_velocity_is_piecewise_linear():
    # q = 1, degree 1: the straight segments, cost sum |w_{i+1} - w_i|^2 / T_i
    W = np.array([[0.0, 0.0], [1.0, 2.0], [4.0, 2.0]])
    T = np.array([0.5, 3.0])
    res = solve_min_snap(W, T, degree=1, derivative=1)
    np.testing.assert_allclose(res.trajectory(0.25), [0.5, 1.0])
    np.testing.assert_allclose(res.trajectory(2.0), [2.5, 2.0])
    assert res.cost == pytest.approx(5 / 0.5 + 9 / 3.0)


def test_closed_form_name_with_a_higher_degree():
    # degree > 2q-1: the registry's generic closed_form backend if registered, else a clear error
    import solvers.qp
    from solvers.errors import SolverNotFound

    rng = np.random.default_rng(12)
    W = random_walk(rng, 4)
    T = np.ones(4)
    if "closed_form" in solvers.qp.available():
        res = solve_min_snap(W, T, degree=9, backend="closed_form")
        assert res.method == "qp" and res.cost == pytest.approx(solve_min_snap(W, T).cost, rel=1e-8)
    else:
        with pytest.raises(SolverNotFound, match="needs the generic closed_form"):
            solve_min_snap(W, T, degree=9, backend="closed_form")
