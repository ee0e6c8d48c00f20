"""Velocity and acceleration limits: exact maxima, uniform time scaling, toppra retiming.

Exact maxima. On a piece, :math:`s(\\tau) = \\|\\sigma^{(r)}\\|^2` is a polynomial in the
normalized time; its maximum on [0, 1] is at an end or at a real root of :math:`s'`.
:func:`max_derivative_norm` evaluates every such candidate (plus a uniform grid, as a
guard against inaccurate roots), so it returns the true maximum, not a sampled one.

Uniform time scaling :math:`\\sigma_\\alpha(t) = \\sigma(t/\\alpha)` (durations
:math:`\\alpha T`) divides velocity by :math:`\\alpha` and acceleration by
:math:`\\alpha^2`, so

.. math::

    \\alpha = \\max\\Big(\\frac{\\max\\|\\dot\\sigma\\|}{v_{max}},
                     \\sqrt{\\frac{\\max\\|\\ddot\\sigma\\|}{a_{max}}}\\Big)

meets both limits (tightly for the binding one). The rest-to-rest min-snap optimum is
invariant in shape under this scaling (:math:`J^*(\\alpha T) = \\alpha^{1-2q} J^*(T)` and
the scaled trajectory is optimal for the scaled durations); non-zero given end
derivatives are divided by :math:`\\alpha^r` too, so do not scale a receding-horizon
window that must match a seam.

toppra (Pham & Pham, "A New Approach to Time-Optimal Path Parametrization Based on
Reachability Analysis", IEEE T-RO 34(3), 2018) computes the time-optimal traversal
:math:`s(t)` of the trajectory's path under the limits (velocity norm exactly, as the
second-order constraint :math:`\\|p'(s)\\|^2 \\dot s^2 \\le v_{max}^2`; acceleration norm
by an inscribed polygon/polytope of directions). :func:`retime_toppra` works in four steps:

1. The input is first scaled uniformly until a limit is tight (:func:`scale_to_limits`),
   and its time is the path parameter :math:`s`, so that :math:`\\dot s \\approx 1`
   wherever the uniform scaling is tight: the problem toppra sees no longer depends on
   how fast the input was, and its numbers are near 1.
2. At the rest ends the tangent :math:`p'(s)` vanishes (as :math:`s^{q-1}`), so nothing
   bounds :math:`\\dot s` there but :math:`\\dot s \\le 5` (``SD_BOUND``: five times the
   uniform scaling's speed). Looser bounds make toppra report ordinary paths
   uncontrollable (measured: 18 of the 126 cases below with 1000; before step 1 existed,
   a bound of 100 times the uniform speed-up failed whenever the speed limit bound and
   the acceleration limit was generous); tighter ones slow the ends down.
3. :math:`p(s(t))` is not a polynomial of degree 7 (:math:`s(t)` is piecewise quadratic),
   so the result is a *refit*: a min-snap trajectory (rest to rest, degree :math:`2q-1`)
   through the path's points at times spread evenly over toppra's time law within each
   input piece (always through the input's knots). toppra's law is bang-bang in the
   acceleration, which a smooth refit cannot follow where a phase is short (the start
   of a speed-limited flight takes milliseconds), so the refit's pieces that exceed a
   limit are lengthened, :math:`T_i \\leftarrow T_i \\sqrt{\\max(1, f_i)}` with :math:`f_i`
   the piece's worst ratio of exact maximum to limit (speed, or the square root for
   acceleration), keeping the best of a few rounds.
4. The refit is scaled uniformly by the least :math:`\\alpha \\ge 1` that meets both limits
   exactly. If it is still slower than the uniform scaling of step 1 (the same path,
   exactly, within the limits), that scaling is returned instead, and
   :attr:`ToppraRetiming.method` says so: the retiming is never slower than
   ``scale_to_limits(..., allow_speedup=True)``.

Measured on 126 cases (six 2-D and 3-D random walks of 5 to 99 pieces, seven limit
pairs from speed- to acceleration-bound, inputs at 0.2, 1 and 5 m/s): no failure, the
same result whatever the input's speed, 2-14 % (median 6 %) slower than toppra's
time-optimal duration and 22-57 % (median 38 %) faster than uniform scaling. An input
whose pieces have very uneven durations (a min-snap loop) can fall back to step 1.
The result passes through the input's knots and deviates from its path between refit
points only by the smoothing.

toppra is an optional extra (``pip install "mrfswarm[toppra]"``): :func:`require_toppra`
checks it is installed (by ``importlib.util.find_spec``, before any work) and raises
:class:`~solvers.errors.SolverNotFound` naming the extra otherwise.
"""

from __future__ import annotations

import importlib.util
import logging
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from mrfswarm.trajectory.bernstein import control_point_matrix
from mrfswarm.trajectory.piece_stack import PIECE_CHUNK, map_coefficients, squared_norms, stacked_tau_coefficients
from mrfswarm.trajectory.polynomial import PiecewisePolynomial
from mrfswarm.trajectory.problem import DEFAULT_DERIVATIVE
from solvers.errors import InvalidProblem, SolverNotFound

log = logging.getLogger(__name__)


def piece_extrema(c: np.ndarray, minimum: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Exact max (or min) over tau in [0, 1] of ||p(tau)|| for a stack of vector polynomials.

    ``c`` is (P, n, dim) coefficients in increasing power of tau. With s = sum_d p_d^2,
    the extremum is at tau = 0, 1 or a real root of s' in (0, 1); the roots of all pieces
    are the eigenvalues of their companion matrices, computed in one stacked call. A
    fixed grid of 33 points is added to the candidates (guarding degenerate leading
    coefficients). Returns the extrema (P,) and the tau where each occurs.
    """
    P, n, _ = c.shape
    s = np.zeros((P, 2 * n - 1))
    for k in range(n):
        s[:, k:k + n] += np.einsum("id,ijd->ij", c[:, k, :], c)
    ds = s[:, 1:] * np.arange(1, 2 * n - 1)  # (P, m + 1), degree m = 2n - 3
    grid = np.broadcast_to(np.linspace(0.0, 1.0, 33), (P, 33))
    m = ds.shape[1] - 1
    if m >= 1:
        scale = np.abs(ds).max(axis=1, keepdims=True)
        a = ds / np.where(scale > 0, scale, 1.0)
        lead = a[:, -1:]
        lead = np.where(np.abs(lead) < 1e-13, 1e-13, lead)  # degree drop: roots go far away, grid covers
        comp = np.zeros((P, m, m))
        comp[:, np.arange(1, m), np.arange(m - 1)] = 1.0
        comp[:, :, -1] = -a[:, :m] / lead
        r = np.linalg.eigvals(comp)
        ok = (np.abs(r.imag) < 1e-7) & (r.real > 0) & (r.real < 1)
        tau = np.concatenate([grid, np.where(ok, r.real, 0.0)], axis=1)
    else:
        tau = grid
    V = tau[:, :, None] ** np.arange(n)[None, None, :]  # (P, C, n)
    vals = np.linalg.norm(np.einsum("pck,pkd->pcd", V, c), axis=-1)
    j = np.argmin(vals, axis=1) if minimum else np.argmax(vals, axis=1)
    return vals[np.arange(P), j], tau[np.arange(P), j]


def max_derivative_norms(trajectories: list[PiecewisePolynomial], order: int) -> np.ndarray:
    r"""Exact maxima over time of :math:`\|\sigma^{(r)}(t)\|`, one per trajectory (vectorized)."""
    cs = [tr.derivative(order).tau_coefficients() for tr in trajectories]  # values in tau equal values in t
    n = max(c.shape[1] for c in cs)
    stack = np.concatenate([np.pad(c, ((0, 0), (0, n - c.shape[1]), (0, 0))) for c in cs])
    vals, _ = piece_extrema(stack)
    ends = np.cumsum([c.shape[0] for c in cs])
    return np.array([v.max() for v in np.split(vals, ends[:-1])])


def max_derivative_norm_all(trajectories: list[PiecewisePolynomial], order: int) -> float:
    r"""Exact maximum over all ``trajectories`` and times of :math:`\|\sigma^{(r)}(t)\|`.

    Only pieces whose control-point bound (the largest control-point norm, an upper bound
    on the piece's maximum) exceeds the largest sampled value (a lower bound on the
    answer) are solved exactly, so the cost is a few evaluations per piece: the samples
    and control points of all pieces are a few matrix products
    (:mod:`~mrfswarm.trajectory.piece_stack`).
    """
    c = stacked_tau_coefficients(trajectories, order)  # (n, P, dim); values in tau equal values in t
    n, P = c.shape[:2]
    tau = np.linspace(0.0, 1.0, 9)
    W = np.vstack([tau[:, None] ** np.arange(n), control_point_matrix(n - 1)])  # values at tau, control points
    sampled2 = -np.inf
    bound2 = np.empty(P)
    for s in range(0, P, PIECE_CHUNK):
        sq = squared_norms(map_coefficients(W, c[:, s:s + PIECE_CHUNK]))  # (9 + n, p)
        sampled2 = max(sampled2, float(sq[:len(tau)].max()))
        bound2[s:s + PIECE_CHUNK] = sq[len(tau):].max(axis=0)
    sampled, bound = np.sqrt(sampled2), np.sqrt(bound2)  # sqrt is monotone: the max of the norms
    keep = bound >= sampled
    if not keep.any():
        return float(sampled)
    vals, _ = piece_extrema(np.ascontiguousarray(c[:, keep].transpose(1, 0, 2)))
    return float(max(sampled, vals.max()))


def max_derivative_norm(trajectory: PiecewisePolynomial, order: int) -> tuple[float, float]:
    r"""The exact maximum over time of :math:`\|\sigma^{(r)}(t)\|` and a time where it occurs.

    Parameters
    ----------
    trajectory
        The trajectory.
    order
        ``r`` (1 velocity, 2 acceleration, ...).

    Returns
    -------
    value : float
    time : float
    """
    vals, tau = piece_extrema(trajectory.derivative(order).tau_coefficients())
    i = int(np.argmax(vals))
    return float(vals[i]), float(trajectory.knots[i] + tau[i] * trajectory.durations[i])


@dataclass(frozen=True)
class TimeScaling:
    """Result of :func:`scale_to_limits`.

    Attributes
    ----------
    trajectory
        The scaled trajectory.
    alpha
        Time scale applied (durations multiplied by it).
    v_peak, a_peak
        Exact maxima of speed and acceleration norm after scaling.
    """

    trajectory: PiecewisePolynomial
    alpha: float
    v_peak: float
    a_peak: float


def _check_limit(name: str, value: float | None) -> None:
    if value is not None and not (np.isfinite(value) and value > 0):
        raise InvalidProblem(f"{name} must be positive and finite, got {value}")


def scale_to_limits(trajectory: PiecewisePolynomial, v_max: float | None = None, a_max: float | None = None,
                    *, allow_speedup: bool = False) -> TimeScaling:
    """Uniformly slow ``trajectory`` down (or speed it up) to meet ``v_max`` and ``a_max``.

    Parameters
    ----------
    trajectory
        The trajectory.
    v_max, a_max
        Limits on the speed and acceleration norms; ``None`` ignores one.
    allow_speedup
        Also speed up a trajectory below both limits, until one is tight
        (``alpha < 1``); by default ``alpha >= 1``.

    Returns
    -------
    TimeScaling

    Raises
    ------
    InvalidProblem
        A non-positive or non-finite limit, or a scale so extreme that the scaled
        coefficients would leave the floating-point range.
    """
    _check_limit("v_max", v_max)
    _check_limit("a_max", a_max)
    v = max_derivative_norm(trajectory, 1)[0]
    a = max_derivative_norm(trajectory, 2)[0]
    need = [0.0]
    if v_max is not None:
        need.append(v / v_max)
    if a_max is not None:
        need.append(np.sqrt(a / a_max))
    alpha = max(need) * (1.0 + 1e-12)  # the limits hold after rounding too
    if alpha == 0.0:
        alpha = 1.0
    if not allow_speedup:
        alpha = max(alpha, 1.0)
    if trajectory.degree * abs(np.log(alpha)) > 600:  # coefficients / alpha**k would leave the double range
        raise InvalidProblem(f"meeting the limits (v_max {v_max}, a_max {a_max}) needs time scaled by {alpha:.3g}, "
                             "beyond floating-point range; the limits do not fit this trajectory's scale")
    out = trajectory.time_scaled(alpha) if alpha != 1.0 else trajectory
    return TimeScaling(out, float(alpha), v / alpha, a / alpha**2)


@lru_cache(maxsize=8)
def _inscribed_directions(dim: int) -> tuple[np.ndarray, float]:
    """Unit directions ``D`` and a factor ``h`` such that ``D @ a <= h * a_max`` implies ``|a| <= a_max``."""
    if dim == 1:
        return np.array([[1.0], [-1.0]]), 1.0
    if dim == 2:
        k = 16
        ang = 2 * np.pi * np.arange(k) / k
        return np.c_[np.cos(ang), np.sin(ang)], float(np.cos(np.pi / k))
    from scipy.spatial import HalfspaceIntersection

    k = 64 if dim == 3 else 32 * dim
    rng = np.random.default_rng(0)
    if dim == 3:  # Fibonacci sphere
        i = np.arange(k) + 0.5
        phi = np.arccos(1 - 2 * i / k)
        th = np.pi * (1 + 5**0.5) * i
        D = np.c_[np.cos(th) * np.sin(phi), np.sin(th) * np.sin(phi), np.cos(phi)]
    else:
        D = rng.normal(size=(k, dim))
        D /= np.linalg.norm(D, axis=1, keepdims=True)
        D = np.vstack([D, np.eye(dim), -np.eye(dim)])
    hs = HalfspaceIntersection(np.c_[D, -np.ones(len(D))], np.zeros(dim))
    R = float(np.max(np.linalg.norm(hs.intersections, axis=1)))  # circumradius of {D a <= 1}
    return D, 1.0 / R


TOPPRA_EXTRA = "toppra"


def require_toppra() -> None:
    """Fail early, and in one line, when toppra is not installed.

    Only a missing module counts as "not installed"; a toppra that is installed but
    fails to import raises its own error when :func:`retime_toppra` imports it.

    Raises
    ------
    SolverNotFound
        toppra is not installed; the message names the pip extra.
    """
    if importlib.util.find_spec("toppra") is None:
        raise SolverNotFound("toppra retiming needs toppra, which is not installed: "
                             f'pip install "mrfswarm[{TOPPRA_EXTRA}]"')


@dataclass(frozen=True)
class ToppraRetiming:
    """Result of :func:`retime_toppra`.

    Attributes
    ----------
    trajectory
        The retimed trajectory within the limits (see the module doc).
    method
        ``"toppra"`` (the refit of toppra's time law) or ``"uniform"`` (the input scaled
        uniformly until a limit is tight, when the refit was slower).
    path_positions, times
        toppra's time law: gridpoints ``s`` (times of the input trajectory) and the
        times at which the time-optimal motion reaches them.
    refit_positions
        Times of the input trajectory whose points the refit passes through at its
        knots (before the final scaling); empty for ``"uniform"``.
    toppra_duration
        Duration of toppra's time-optimal motion (a lower bound on this path).
    alpha
        Uniform slow-down applied to the refit (>= 1), or the scaling of the input for
        ``"uniform"``.
    v_peak, a_peak
        Exact maxima of the returned trajectory.
    """

    trajectory: PiecewisePolynomial
    method: str
    path_positions: np.ndarray
    times: np.ndarray
    refit_positions: np.ndarray
    toppra_duration: float
    alpha: float
    v_peak: float
    a_peak: float


SD_BOUND = 5.0  # bound on ds/dt of the pre-scaled path (step 2 of the module doc)


def _limit_ratios(trajectory: PiecewisePolynomial, v_max: float, a_max: float) -> np.ndarray:
    """Per piece, the worst of (exact max speed) / v_max and sqrt((exact max acceleration) / a_max)."""
    v, _ = piece_extrema(trajectory.derivative(1).tau_coefficients())
    a, _ = piece_extrema(trajectory.derivative(2).tau_coefficients())
    return np.maximum(v / v_max, np.sqrt(a / a_max))


def retime_toppra(trajectory: PiecewisePolynomial, v_max: float, a_max: float, *, derivative: int = DEFAULT_DERIVATIVE,
                  gridpoints_per_piece: int = 20, refit_pieces_per_piece: int = 10, stretch_rounds: int = 10,
                  backend: str | None = None) -> ToppraRetiming:
    """Retime ``trajectory`` with toppra under speed and acceleration limits, then refit.

    See the module doc for the four steps (pre-scaling, bounds, refit with local
    stretching, final scaling or the uniform fallback).

    Parameters
    ----------
    trajectory
        A trajectory at rest at both ends (toppra's parametrization starts and stops at rest).
    v_max, a_max
        Limits on the speed and acceleration norms.
    derivative
        Minimized derivative of the refit (4, snap).
    gridpoints_per_piece
        toppra's discretization per input piece (knots always included).
    refit_pieces_per_piece
        Pieces of the refit per input piece, evenly spread in toppra's time.
    stretch_rounds
        At most this many rounds of lengthening the refit's pieces that exceed a limit
        (0: none); stops after 3 rounds without a shorter result.
    backend
        Solver of the refit (see :func:`~mrfswarm.trajectory.min_snap.solve_min_snap`).

    Returns
    -------
    ToppraRetiming

    Raises
    ------
    SolverNotFound
        toppra is not installed (see :func:`require_toppra`).
    InvalidProblem
        A missing, non-positive or non-finite limit, or a non-positive size.
    SolverError
        If toppra fails to parametrize the path.
    """
    _check_toppra_arguments(v_max, a_max, gridpoints_per_piece, refit_pieces_per_piece, stretch_rounds)
    require_toppra()
    from mrfswarm.trajectory.toppra_law import time_optimal_law

    uniform = scale_to_limits(trajectory, v_max, a_max, allow_speedup=True)
    path = uniform.trajectory  # step 1: s = time of the input scaled to the limits
    G = gridpoints_per_piece
    kn = path.knots
    grid = np.concatenate([(kn[:-1, None] + np.arange(G)[None, :] / G * path.durations[:, None]).ravel(), kn[-1:]])
    ss, sd, times = time_optimal_law(path, grid, v_max, a_max, *_inscribed_directions(path.dim))  # step 2
    s_fit, t_fit = _refit_samples(ss, sd, times, G, refit_pieces_per_piece)  # step 3
    best = _refit_with_stretching(path.evaluate(s_fit), np.diff(t_fit), v_max, a_max, derivative, stretch_rounds,
                                  backend)
    sc = scale_to_limits(best, v_max, a_max)
    # step 4: never slower than the uniform scaling of step 1
    if sc.trajectory.duration > path.duration:
        method, out, alpha, v_pk, a_pk, fit_s = "uniform", path, uniform.alpha, uniform.v_peak, uniform.a_peak, ss[:0]
    else:
        method, out, alpha, v_pk, a_pk, fit_s = "toppra", sc.trajectory, sc.alpha, sc.v_peak, sc.a_peak, s_fit
    log.info("toppra: %.3f s time-optimal on the path; refit of %d pieces scaled by %.3f to %.3f s; "
             "uniform scaling %.3f s; returned: %s", times[-1], best.pieces, sc.alpha, sc.trajectory.duration,
             path.duration, method)
    to_input = 1.0 / uniform.alpha  # path parameter -> time of the input trajectory
    return ToppraRetiming(out, method, ss * to_input, times, fit_s * to_input, float(times[-1]), float(alpha),
                          float(v_pk), float(a_pk))


def _check_toppra_arguments(v_max: float, a_max: float, gridpoints_per_piece: int, refit_pieces_per_piece: int,
                            stretch_rounds: int) -> None:
    if v_max is None or a_max is None:
        raise InvalidProblem("retime_toppra needs both v_max and a_max")
    _check_limit("v_max", v_max)
    _check_limit("a_max", a_max)
    if gridpoints_per_piece < 1 or refit_pieces_per_piece < 1 or stretch_rounds < 0:
        raise InvalidProblem(f"gridpoints_per_piece ({gridpoints_per_piece}) and refit_pieces_per_piece "
                             f"({refit_pieces_per_piece}) must be >= 1, stretch_rounds ({stretch_rounds}) >= 0")


def _refit_samples(ss: np.ndarray, sd: np.ndarray, times: np.ndarray, G: int, R: int) -> tuple[np.ndarray, np.ndarray]:
    """Step 3's refit points: ``R`` per input piece, evenly spread in toppra's time (``G`` gridpoints a piece).

    Returns ``(s, t)``: their path parameters (the input's knots exactly) and times.
    """
    t_knots = times[::G]
    t_fit = np.append((t_knots[:-1, None] + np.arange(R)[None, :] / R * np.diff(t_knots)[:, None]).ravel(), times[-1])
    i = np.clip(np.searchsorted(times, t_fit, side="right") - 1, 0, ss.size - 2)
    tau = t_fit - times[i]
    sdd = (sd[i + 1] ** 2 - sd[i] ** 2) / (2.0 * (ss[i + 1] - ss[i]))
    s_fit = np.minimum(ss[i] + sd[i] * tau + 0.5 * sdd * tau**2, ss[i + 1])
    s_fit[::R] = ss[::G]  # exactly the knots
    return s_fit, t_fit


def _refit_with_stretching(points: np.ndarray, T: np.ndarray, v_max: float, a_max: float, derivative: int,
                           rounds: int, backend: str | None) -> PiecewisePolynomial:
    """Step 3's refit through ``points``: lengthen the pieces over a limit for up to ``rounds`` rounds.

    Returns the refit of the shortest duration once scaled to the limits (stops after 3
    rounds without a shorter one, or when every limit holds).
    """
    from mrfswarm.trajectory.min_snap import solve_min_snap

    best, stale = None, 0
    for _ in range(rounds + 1):
        refit = solve_min_snap(points, T, degree=2 * derivative - 1, derivative=derivative,
                               backend=backend).trajectory
        f = _limit_ratios(refit, v_max, a_max)
        if best is None or refit.duration * f.max() < best[0] * (1 - 1e-3):
            best, stale = (refit.duration * f.max(), refit), 0
        else:
            stale += 1
        if stale >= 3 or f.max() <= 1.0 + 1e-3:
            break
        T = T * np.sqrt(np.maximum(f, 1.0))  # damped: lengthening a piece also loads its neighbours
    assert best is not None  # the loop ran at least once
    return best[1]
