"""Time allocation, duration refinement, exact maxima, time scaling to limits, toppra retiming."""

import numpy as np
import pytest

from mrfswarm.trajectory import (
    MinSnapProblem,
    constant_speed_durations,
    cost_and_gradient,
    max_derivative_norm,
    refine_durations,
    retime_toppra,
    scale_to_limits,
    solve_min_snap,
    trapezoidal_durations,
)
from mrfswarm.trajectory.time_allocation import scaled_time_weight, stationary_time_weight
from solvers.errors import InvalidOptions, InvalidProblem
from support.trajectories import random_walk


def dense_max(traj, order, rate=5000):
    t = np.linspace(0, traj.duration, int(traj.duration * rate) + 2)
    return np.linalg.norm(traj(t, order), axis=-1).max()


def test_constant_speed_and_trapezoidal_durations():
    W = np.array([[0.0, 0.0], [3.0, 4.0], [3.0, 4.5]])
    np.testing.assert_allclose(constant_speed_durations(W, 2.0), [2.5, 0.25])
    # v=2, a=4: cruise when d >= 1; d=5 -> 5/2 + 2/4 = 3; d=0.5 -> triangle 2 sqrt(0.5/4)
    np.testing.assert_allclose(trapezoidal_durations(W, 2.0, 4.0), [3.0, 2 * np.sqrt(0.125)])
    with pytest.raises(InvalidProblem, match="coincide"):
        constant_speed_durations([[0, 0], [0, 0]], 1.0)
    with pytest.raises(InvalidProblem, match="speed"):
        constant_speed_durations(W, 0.0)


def test_cost_and_gradient_finite_differences_random_problems():
    rng = np.random.default_rng(0)
    for trial in range(3):
        W = random_walk(rng, 5 + trial, 2 + trial % 2)
        T = rng.uniform(0.3, 3.0, W.shape[0] - 1)
        p = MinSnapProblem(W, T)
        J, g = cost_and_gradient(p)
        for j in range(T.size):
            h = 1e-6 * T[j]
            e = np.zeros_like(T)
            e[j] = h
            fd = (cost_and_gradient(p.with_data(durations=T + e))[0] - cost_and_gradient(p.with_data(durations=T - e))[0]) / (2 * h)
            assert g[j] == pytest.approx(fd, rel=1e-6)


def test_refinement_reaches_a_stationary_point():
    rng = np.random.default_rng(1)
    W = random_walk(rng, 8)
    T0 = constant_speed_durations(W, 1.0)
    k_T = 50.0
    res = refine_durations(W, T0, time_weight=k_T)
    assert res.objective < res.initial_objective
    J, g = cost_and_gradient(MinSnapProblem(W, res.durations))
    assert J == pytest.approx(res.cost)
    # stationarity: dJ/dT_i = -k_T for every (unconstrained) duration
    np.testing.assert_allclose(g, -k_T, rtol=1e-3)
    # Euler: J* = k_T sum(T) / (2q - 1) at the optimum
    assert J == pytest.approx(k_T * res.durations.sum() / 7, rel=1e-4)


def test_refinement_beats_uniform_scaling_of_the_start():
    # the best uniform scaling of T0 is optimal only along one direction; refinement does at least as well
    rng = np.random.default_rng(2)
    W = random_walk(rng, 6, step=(0.2, 3.0))
    T0 = constant_speed_durations(W, 1.0)
    k_T = 10.0
    J0 = cost_and_gradient(MinSnapProblem(W, T0))[0]
    alpha = (7 * J0 / (k_T * T0.sum())) ** (1 / 8)
    F_scaled = alpha**-7 * J0 + k_T * alpha * T0.sum()
    res = refine_durations(W, T0, time_weight=k_T)
    assert res.objective <= F_scaled * (1 + 1e-9)


def test_max_derivative_norm_is_exact():
    rng = np.random.default_rng(3)
    W = random_walk(rng, 6)
    traj = solve_min_snap(W, rng.uniform(0.5, 1.5, 6)).trajectory
    for r in (1, 2, 3):
        v, t = max_derivative_norm(traj, r)
        sampled = dense_max(traj, r)
        assert v >= sampled * (1 - 1e-12)
        assert v == pytest.approx(sampled, rel=1e-5)
        assert np.linalg.norm(traj(t, r)) == pytest.approx(v)


@pytest.mark.parametrize("v_max,a_max", [(0.5, 100.0), (100.0, 0.3), (0.8, 0.8)])
def test_scale_to_limits_meets_them_by_sampling(v_max, a_max):
    rng = np.random.default_rng(4)
    W = random_walk(rng, 6)
    traj = solve_min_snap(W, constant_speed_durations(W, 2.0)).trajectory
    sc = scale_to_limits(traj, v_max, a_max)
    assert sc.alpha >= 1.0
    v, a = dense_max(sc.trajectory, 1), dense_max(sc.trajectory, 2)
    assert v <= v_max * (1 + 1e-9) and a <= a_max * (1 + 1e-9)
    # the binding limit is tight (exact maxima, so tight to rounding)
    assert max(sc.v_peak / v_max, sc.a_peak / a_max) == pytest.approx(1.0, rel=1e-9)
    # the shape is that of the min-snap optimum for the scaled durations
    again = solve_min_snap(W, sc.trajectory.durations).trajectory
    np.testing.assert_allclose(again.coefficients, sc.trajectory.coefficients, atol=1e-8)


def test_scale_to_limits_speedup_only_when_asked():
    traj = solve_min_snap([[0.0, 0.0], [1.0, 0.0]], [10.0]).trajectory
    assert scale_to_limits(traj, 5.0, 5.0).alpha == 1.0
    fast = scale_to_limits(traj, 5.0, 5.0, allow_speedup=True)
    assert fast.alpha < 1.0 and max(fast.v_peak / 5.0, fast.a_peak / 5.0) == pytest.approx(1.0)


@pytest.mark.parametrize("dim", [2, 3])
def test_toppra_retiming_respects_limits_and_waypoints(dim):
    rng = np.random.default_rng(5)
    W = random_walk(rng, 5, dim)
    traj = solve_min_snap(W, constant_speed_durations(W, 3.0)).trajectory
    v_max, a_max = 1.0, 1.5
    out = retime_toppra(traj, v_max, a_max, gridpoints_per_piece=20, refit_pieces_per_piece=5)
    tr = out.trajectory
    assert tr.degree == 7 and tr.pieces == 5 * traj.pieces
    assert dense_max(tr, 1) <= v_max * (1 + 1e-9) and dense_max(tr, 2) <= a_max * (1 + 1e-9)
    np.testing.assert_allclose(tr(tr.knots[::5]), W, atol=1e-9)  # through the input's knots
    for r in (1, 2, 3):
        assert np.abs(tr([0.0, tr.duration], r)).max() < 1e-9
    # on the input's path: refit points are path points, in order
    assert out.method == "toppra" and np.all(np.diff(out.refit_positions) > 0)
    np.testing.assert_allclose(tr(tr.knots), traj(out.refit_positions), atol=1e-9)
    np.testing.assert_allclose(out.path_positions[[0, -1]], [0.0, traj.duration], rtol=1e-12)
    # toppra's time-optimal duration is a lower bound; the refit is close to it and beats uniform scaling
    assert out.toppra_duration <= tr.duration * (1 + 1e-6)
    uniform = scale_to_limits(traj, v_max, a_max, allow_speedup=True).trajectory.duration
    assert tr.duration < uniform
    assert tr.duration < 1.2 * out.toppra_duration


def test_refinement_without_weight_keeps_the_total_and_only_redistributes():
    rng = np.random.default_rng(6)
    W = random_walk(rng, 9, step=(0.2, 3.0))
    T0 = constant_speed_durations(W, 1.0)
    res = refine_durations(W, T0)
    assert res.durations.sum() == pytest.approx(T0.sum(), rel=1e-12)
    J0 = cost_and_gradient(MinSnapProblem(W, T0))[0]
    assert res.cost < 0.95 * J0  # same total, less snap (constant speed is far from optimal here)
    assert res.objective < res.initial_objective
    # the reported weight is the one for which the result is stationary
    _, g = cost_and_gradient(MinSnapProblem(W, res.durations))
    np.testing.assert_allclose(g, -res.time_weight, rtol=2e-3)
    # and the shares are those of any explicit weight (the weight only sets the time scale): the best
    # uniform scaling of the result reaches that weight's optimum
    for k in (1.0, 1e4):
        other = refine_durations(W, T0, time_weight=k)
        alpha = (7 * res.cost / (k * res.durations.sum())) ** (1 / 8)
        F = cost_and_gradient(MinSnapProblem(W, alpha * res.durations))[0] + k * alpha * res.durations.sum()
        assert F == pytest.approx(other.objective, rel=1e-6)
        shares = res.durations / res.durations.sum()
        np.testing.assert_allclose(other.durations / other.durations.sum(), shares, rtol=1e-2)


def test_stationary_time_weight_makes_the_given_total_optimal():
    rng = np.random.default_rng(7)
    W = random_walk(rng, 6)
    T0 = rng.uniform(0.5, 2.0, 6)
    k = stationary_time_weight(W, T0)
    J0 = cost_and_gradient(MinSnapProblem(W, T0))[0]

    def F(alpha):
        return cost_and_gradient(MinSnapProblem(W, alpha * T0))[0] + k * alpha * T0.sum()

    assert F(1.0) < F(0.99) and F(1.0) < F(1.01)
    assert k == pytest.approx(7 * J0 / T0.sum())


def test_scaled_time_weight_is_the_weight_of_the_scaled_optimum():
    rng = np.random.default_rng(8)
    W = random_walk(rng, 7)
    res = refine_durations(W, constant_speed_durations(W, 1.0), time_weight=30.0)
    for alpha in (0.4, 1.7):
        _, g = cost_and_gradient(MinSnapProblem(W, alpha * res.durations))
        np.testing.assert_allclose(g, -scaled_time_weight(30.0, alpha), rtol=2e-3)


def test_refinement_guards():
    W = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]])
    for bad in (0.0, -1.0, np.nan, np.inf):
        with pytest.raises(InvalidProblem, match="time_weight must be positive"):
            refine_durations(W, [1.0, 1.0], time_weight=bad)
    for bad in (np.inf, np.nan, -1.0):  # inf stopped after one iteration, far from the optimum, "converged"
        with pytest.raises(InvalidOptions, match=f"^tol must be finite and >= 0, got {bad}$"):
            refine_durations(W, [1.0, 1.0], time_weight=1.0, tol=bad)
    # keeping the total needs homogeneous ends; a given non-zero end velocity breaks it
    with pytest.raises(InvalidProblem, match="needs ends at rest or free"):
        refine_durations(W, [1.0, 1.0], start=[[1.0, 0.0]])
    res = refine_durations(W, [1.0, 1.0], start=[[1.0, 0.0]], time_weight=5.0)
    assert res.objective <= res.initial_objective
    # free ends are homogeneous too; through four points a cubic costs nothing, so nothing moves
    W4 = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [3.0, 2.0]])
    zero = refine_durations(W4, [1.0, 2.0, 1.5], start="free", end="free")
    assert zero.cost == 0.0 and zero.iterations == 0
    np.testing.assert_array_equal(zero.durations, [1.0, 2.0, 1.5])
    rng = np.random.default_rng(10)
    W6 = random_walk(rng, 6)
    T6 = constant_speed_durations(W6, 1.0)
    free = refine_durations(W6, T6, start="free", end="free")
    assert free.durations.sum() == pytest.approx(T6.sum())
    assert free.cost < cost_and_gradient(MinSnapProblem(W6, T6, start="free", end="free"))[0]


def test_scale_to_limits_rejects_limits_beyond_floating_point():
    traj = solve_min_snap([[0.0, 0.0], [1.0, 0.0]], [1.0]).trajectory
    with pytest.raises(InvalidProblem, match="beyond floating-point range"):
        scale_to_limits(traj, 1e-300, None)
    with pytest.raises(InvalidProblem, match="beyond floating-point range"):
        scale_to_limits(traj, 1e300, 1e300, allow_speedup=True)


@pytest.mark.parametrize("v_max,a_max", [(1.0, 4.0), (0.1, 1.0), (1.0, 100.0)], ids=["v1-a4", "v0.1-a1", "v1-a100"])
def test_toppra_retiming_does_not_depend_on_the_input_speed(v_max, a_max):
    # speed-bound limits with a generous acceleration: toppra used to report the path uncontrollable
    rng = np.random.default_rng(9)
    W = random_walk(rng, 8)
    outs = [retime_toppra(solve_min_snap(W, constant_speed_durations(W, speed)).trajectory, v_max, a_max)
            for speed in (0.2, 5.0)]
    for out in outs:
        tr = out.trajectory
        assert out.method == "toppra"
        assert max_derivative_norm(tr, 1)[0] <= v_max * (1 + 1e-9)
        assert max_derivative_norm(tr, 2)[0] <= a_max * (1 + 1e-9)
        assert dense_max(tr, 1, 2000) <= v_max * (1 + 1e-9) and dense_max(tr, 2, 2000) <= a_max * (1 + 1e-9)
        # lengthening the refit's overloaded pieces brings it within 2 % of toppra's optimum here (4-14 % without)
        assert tr.duration < 1.03 * out.toppra_duration
    np.testing.assert_allclose(outs[0].trajectory.durations, outs[1].trajectory.durations, rtol=1e-6)
    np.testing.assert_allclose(outs[0].trajectory.coefficients, outs[1].trajectory.coefficients, atol=1e-6)


def test_toppra_retiming_falls_back_to_uniform_scaling_when_the_refit_is_slower():
    # a piece 10x slower than its neighbours makes min-snap loop; the refit of toppra's law cannot keep up
    rng = np.random.default_rng(7)
    W = random_walk(rng, 8)
    T = constant_speed_durations(W, 1.0)
    T[3] *= 10
    T[5] *= 5
    traj = solve_min_snap(W, T).trajectory
    out = retime_toppra(traj, 1.0, 1.5)
    uniform = scale_to_limits(traj, 1.0, 1.5, allow_speedup=True)
    assert out.method == "uniform" and out.refit_positions.size == 0
    np.testing.assert_allclose(out.trajectory.coefficients, uniform.trajectory.coefficients)
    assert out.alpha == uniform.alpha and out.toppra_duration < out.trajectory.duration


def test_toppra_missing_is_one_clear_error(monkeypatch):
    import importlib.util

    from solvers.errors import SolverNotFound

    find_spec = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "toppra" else find_spec(name, *a))
    traj = solve_min_snap([[0.0, 0.0], [1.0, 0.0]], [1.0]).trajectory
    with pytest.raises(SolverNotFound, match=r'pip install "mrfswarm\[toppra\]"'):
        retime_toppra(traj, 1.0, 1.0)
