"""PiecewisePolynomial: evaluation, derivatives, sampling, concatenation, restriction, cost."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import quad

from mrfswarm.trajectory import PiecewisePolynomial, concatenate, integral_squared_derivative, seam_jumps
from mrfswarm.trajectory.polynomial import cost_hessian, piece_cost_gradients, piece_costs, tau_to_time, time_to_tau
from solvers.errors import InvalidProblem


def random_traj(rng, M=4, D=7, dim=2):
    return PiecewisePolynomial(rng.uniform(0.3, 2.0, M), rng.normal(size=(M, D + 1, dim)))


def test_evaluation_matches_numpy_polyval_per_piece():
    rng = np.random.default_rng(0)
    tr = random_traj(rng)
    for i in range(tr.pieces):
        s = np.linspace(0, tr.durations[i], 7)[:-1]
        t = tr.knots[i] + s
        for r in range(4):
            expect = np.stack([np.polynomial.polynomial.polyval(s, np.polynomial.polynomial.polyder(tr.coefficients[i, :, d], r))
                               for d in range(tr.dim)], axis=-1)
            np.testing.assert_allclose(tr(t, r), expect, rtol=1e-12, atol=1e-12)


def test_evaluate_shapes_and_clamping():
    rng = np.random.default_rng(1)
    tr = random_traj(rng, dim=3)
    assert tr(0.5).shape == (3,)
    assert tr(np.zeros((4, 5))).shape == (4, 5, 3)
    np.testing.assert_allclose(tr(-1.0), tr(0.0))
    np.testing.assert_allclose(tr(tr.duration + 5), tr(tr.duration))
    assert np.all(tr(0.3, derivative=8) == 0)
    with pytest.raises(InvalidProblem):
        tr(0.0, derivative=-1)


def test_evaluate_names_a_time_or_an_order_it_cannot_take():
    """NaN times gave NaN positions without a word (``ContinuousPlan.positions`` refused them, a robot's own
    ``evaluate``, which the README points to, did not); an order of 1.5 ended in "slice indices must be
    integers", a string time in NumPy's "could not convert string to float" (a library tour)."""
    tr = random_traj(np.random.default_rng(1))
    with pytest.raises(InvalidProblem, match=r"^t must not be NaN, got \[0\.5, nan\]$"):
        tr.evaluate(np.array([0.5, np.nan]))
    with pytest.raises(InvalidProblem, match=r"^t = 'a': must be an array of real numbers"):
        tr.evaluate("a")
    for order in (1.5, True, "1"):
        with pytest.raises(InvalidProblem, match=r"^derivative order must be an integer >= 0, got "):
            tr.evaluate(0.5, order)
        with pytest.raises(InvalidProblem, match=r"^derivative order must be an integer >= 0, got "):
            tr.derivative(order)
    np.testing.assert_allclose(tr.evaluate(np.inf), tr.evaluate(tr.duration))  # clamped, as documented
    np.testing.assert_allclose(tr.evaluate([0.5], np.int64(2)), tr.evaluate(np.array([0.5]), 2))


def test_derivative_object_matches_evaluate():
    rng = np.random.default_rng(2)
    tr = random_traj(rng)
    t = np.linspace(0, tr.duration, 101)
    for r in range(1, 5):
        np.testing.assert_allclose(tr.derivative(r)(t), tr(t, r), rtol=1e-11, atol=1e-9)


def test_sample_rate_and_end():
    tr = PiecewisePolynomial([0.55, 0.5], np.zeros((2, 8, 2)))
    t, p = tr.sample(10.0)
    assert t[0] == 0 and t[-1] == pytest.approx(1.05) and p.shape == (len(t), 2)
    np.testing.assert_allclose(np.diff(t[:-1]), 0.1)


def test_validation():
    with pytest.raises(InvalidProblem, match="duration"):
        PiecewisePolynomial([1.0, 0.0], np.zeros((2, 8, 2)))
    with pytest.raises(InvalidProblem, match="shape"):
        PiecewisePolynomial([1.0], np.zeros((2, 8, 2)))
    with pytest.raises(InvalidProblem, match="finite"):
        PiecewisePolynomial([1.0], np.full((1, 8, 2), np.nan))
    # NumPy's "could not convert string to float: 'a'", naming neither array; None read as a NaN duration (a tour)
    with pytest.raises(InvalidProblem, match=r"^durations = \['a'\]: must be an array of real numbers"):
        PiecewisePolynomial(["a"], np.zeros((1, 8, 2)))
    with pytest.raises(InvalidProblem, match=r"^durations = None: must be an array of real numbers, not None$"):
        PiecewisePolynomial(None, np.zeros((1, 8, 2)))
    with pytest.raises(InvalidProblem, match=r"^coefficients = \[\[\['a'\]\]\]: must be an array of real numbers"):
        PiecewisePolynomial([1.0], [[["a"]]])


def test_tau_time_round_trip():
    rng = np.random.default_rng(3)
    tr = random_traj(rng)
    np.testing.assert_allclose(tau_to_time(time_to_tau(tr.coefficients, tr.durations), tr.durations), tr.coefficients)


def test_concatenate_and_seams():
    rng = np.random.default_rng(4)
    a = random_traj(rng, M=2, D=5)
    b = random_traj(rng, M=3, D=7)
    c = concatenate([a, b])
    assert c.pieces == 5 and c.degree == 7 and c.duration == pytest.approx(a.duration + b.duration)
    t = np.linspace(0, a.duration, 30, endpoint=False)
    np.testing.assert_allclose(c(t), a(t))
    np.testing.assert_allclose(c(a.duration + np.linspace(0, b.duration, 30)), b(np.linspace(0, b.duration, 30)))
    with pytest.raises(InvalidProblem):
        concatenate([a, random_traj(rng, dim=3)])
    # seam_jumps: value at start of piece i+1 minus value at end of piece i
    j = seam_jumps(c, 2)
    for r in range(3):
        np.testing.assert_allclose(j[1, r], b(0.0, r) - a(a.duration, r), rtol=1e-10, atol=1e-10)


@settings(max_examples=30, deadline=None)
@given(st.floats(0.0, 0.95), st.floats(0.05, 1.0), st.integers(0, 2**31 - 1))
def test_restricted_is_the_same_curve(frac0, span, seed):
    rng = np.random.default_rng(seed)
    tr = random_traj(rng, M=3)
    t0 = frac0 * tr.duration
    t1 = min(tr.duration, t0 + span * (tr.duration - t0))
    if t1 - t0 < 1e-6:
        return
    sub = tr.restricted(t0, t1)
    assert sub.duration == pytest.approx(t1 - t0, rel=1e-12)
    s = np.linspace(0, sub.duration, 50)
    for r in range(3):
        np.testing.assert_allclose(sub(s, r), tr(t0 + s, r), rtol=1e-8, atol=1e-8)


def test_time_scaled_laws():
    rng = np.random.default_rng(5)
    tr = random_traj(rng)
    alpha = 2.5
    sc = tr.time_scaled(alpha)
    t = np.linspace(0, tr.duration, 40)
    for r in range(4):
        np.testing.assert_allclose(sc(alpha * t, r), tr(t, r) / alpha**r, rtol=1e-10, atol=1e-10)
    q = 4
    assert integral_squared_derivative(sc, q) == pytest.approx(alpha ** (1 - 2 * q) * integral_squared_derivative(tr, q))


@pytest.mark.parametrize("q", [1, 2, 3, 4])
def test_integral_squared_derivative_matches_quadrature(q):
    rng = np.random.default_rng(q)
    tr = random_traj(rng, M=3)
    num = sum(quad(lambda t: float(np.sum(tr(t, q) ** 2)), tr.knots[i], tr.knots[i + 1], epsabs=0, epsrel=1e-12)[0]
              for i in range(tr.pieces))
    assert integral_squared_derivative(tr, q) == pytest.approx(num, rel=1e-9)


@pytest.mark.parametrize("D, q", [(7, 4), (9, 4), (5, 3), (7, 1)])
def test_piece_costs_match_gauss_legendre_quadrature_on_short_and_long_pieces(D, q):
    """Each piece's cost against Gauss-Legendre of |sigma^(q)|^2 with D + 1 nodes (exact to degree 2D + 1)."""
    rng = np.random.default_rng(D * 10 + q)
    T = np.array([0.01, 0.3, 1.0, 7.0, 100.0])
    tr = PiecewisePolynomial(T, time_to_tau(rng.normal(size=(T.size, D + 1, 3)), 1.0 / T))  # tau-coefficients ~ 1
    nodes, weights = np.polynomial.legendre.leggauss(D + 1)
    expect = []
    for i in range(tr.pieces):
        t = tr.knots[i] + (nodes + 1) / 2 * T[i]
        expect.append(T[i] / 2 * weights @ np.sum(tr(t, q) ** 2, axis=-1))
    got = piece_costs(tr.tau_coefficients(), T, q)
    np.testing.assert_allclose(got, expect, rtol=1e-9)
    assert integral_squared_derivative(tr, q) == pytest.approx(sum(expect), rel=1e-9)


@pytest.mark.parametrize("q", [1, 3, 4])
def test_piece_cost_gradients_match_finite_differences(q):
    rng = np.random.default_rng(20 + q)
    c = rng.normal(size=(3, 8, 2))
    T = np.array([0.5, 1.3, 2.2])
    by_c, by_T = piece_cost_gradients(c, T, q)
    h = 1e-6
    for i, k, d in ((0, 7, 0), (1, 5, 1), (2, q, 0)):
        up, down = c.copy(), c.copy()
        up[i, k, d] += h
        down[i, k, d] -= h
        fd = (piece_costs(up, T, q) - piece_costs(down, T, q))[i] / (2 * h)
        assert by_c[i, k, d] == pytest.approx(fd, rel=1e-6)
    for i in range(3):
        dT = np.zeros(3)
        dT[i] = h * T[i]
        fd = (piece_costs(c, T + dT, q) - piece_costs(c, T - dT, q))[i] / (2 * dT[i])
        assert by_T[i] == pytest.approx(fd, rel=1e-6)
    assert np.all(by_c[:, :q] == 0)  # coefficients below q do not reach the q-th derivative


def test_cost_hessian_known_entries():
    H = cost_hessian(7, 4)
    assert H[4, 4] == 576 and H[7, 7] == pytest.approx(100800)
    assert np.all(H[:4] == 0) and np.all(H[:, :4] == 0)
    assert np.all(np.linalg.eigvalsh(H[4:, 4:]) > 0)


def test_with_degree():
    rng = np.random.default_rng(6)
    tr = random_traj(rng, D=5)
    up = tr.with_degree(7)
    assert up.degree == 7 and np.all(up.coefficients[:, 6:] == 0)
    assert up.with_degree(5).degree == 5
    with pytest.raises(InvalidProblem, match="cannot lower"):
        tr.with_degree(3)
