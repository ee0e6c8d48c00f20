"""Time allocation, duration refinement, exact maxima, time scaling to limits, toppra retiming."""

import numpy as np
import pytest
from test_trajectory_support import random_walk

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
from solvers.errors import InvalidProblem


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
    np.testing.assert_allclose(tr(tr.knots), traj(out.path_positions[::4]), atol=1e-9)
    # toppra's time-optimal duration is a lower bound; the refit is close to it and beats uniform scaling
    assert out.toppra_duration <= tr.duration * (1 + 1e-6)
    uniform = scale_to_limits(traj, v_max, a_max, allow_speedup=True).trajectory.duration
    assert tr.duration < uniform
    assert tr.duration < 1.2 * out.toppra_duration
