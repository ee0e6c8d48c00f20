"""Piece durations: initial guesses and their refinement by the cost's duration gradient.

Initial guesses, per segment of length :math:`d_i = \\|w_{i+1} - w_i\\|`:

- constant speed :math:`v`: :math:`T_i = d_i / v`;
- trapezoidal velocity profile (rest to rest, speed :math:`v_{max}`, acceleration
  :math:`a_{max}`): :math:`T_i = d_i / v_{max} + v_{max} / a_{max}` when the segment
  is long enough to cruise (:math:`d_i \\ge v_{max}^2 / a_{max}`), else the triangular
  profile :math:`T_i = 2 \\sqrt{d_i / a_{max}}`.

Refinement (Richter, Bry & Roy, "Polynomial trajectory planning for aggressive
quadrotor flight in dense indoor environments", ISRR 2013): minimize

.. math::

    F(T) = J^*(T) + k_T \\sum_i T_i

over :math:`T_i \\ge T_{min}`, with the exact gradient :math:`dJ^*/dT` of the closed form
(:func:`~mrfswarm.trajectory.banded.solve_banded`, adjoint method). The optimizer is
L-BFGS-B (a projected quasi-Newton method) in :math:`\\log T`, where :math:`J^*
\\propto T^{1-2q}` is far better scaled than in :math:`T`.

For a rest-to-rest problem :math:`J^*(\\alpha T) = \\alpha^{1-2q} J^*(T)`, so by Euler's
theorem :math:`\\sum_i T_i\\, \\partial J^*/\\partial T_i = (1-2q) J^*`; at a stationary point
of :math:`F` this gives :math:`J^* = k_T \\sum_i T_i / (2q - 1)`.

The same homogeneity (it holds whenever each end is at rest or free) makes the time
weight a pure choice of time scale: :math:`F_{k}(\\alpha T) = \\alpha^{1-2q} F_{k'}(T)`
with :math:`k' = k\\, \\alpha^{2q}`, so the minimizers for different weights are uniform
time scalings of one another, and the optimal *shares* :math:`T_i / \\sum_j T_j` (those
minimizing :math:`J^*(T) (\\sum_i T_i)^{2q-1}`) do not depend on :math:`k_T`. Hence:

- :func:`stationary_time_weight` gives the weight for which the given durations' total is
  optimal along their own scaling (:math:`k_T = (2q-1) J^*(T) / \\sum_i T_i`), a start at
  which the optimizer only redistributes time;
- ``refine_durations(..., time_weight=None)`` redistributes the given total duration
  over the pieces (the least cost at that total) and reports the weight for which the
  result is optimal;
- a refined trajectory slowed down or sped up uniformly by :math:`\\alpha` (e.g. by
  :func:`~mrfswarm.trajectory.retiming.scale_to_limits` to meet velocity and acceleration
  limits) is the optimum for the weight :math:`k_T\\, \\alpha^{-2q}`
  (:func:`scaled_time_weight`).

The objective trades snap against time; it does not contain the limits. Scaled until a
limit is tight, the refined durations still minimize :math:`J^* + k_T \\sum T` for the
weight that scaling implies, so their objective is at most that of any uniform scaling of
the initial durations; but they are not necessarily the shortest flight within the
limits (measured: sometimes slower than the initial durations scaled to the same limits;
for the shortest, retime the path: :func:`~mrfswarm.trajectory.retiming.retime_toppra`).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from mrfswarm.trajectory.banded import solve_banded
from mrfswarm.trajectory.problem import DEFAULT_DEGREE, DEFAULT_DERIVATIVE, EndSpec, MinSnapProblem
from solvers.errors import InvalidOptions, InvalidProblem

log = logging.getLogger(__name__)


def _segment_lengths(waypoints: np.ndarray) -> np.ndarray:
    W = np.asarray(waypoints, dtype=float)
    if W.ndim != 2 or W.shape[0] < 2:
        raise InvalidProblem(f"waypoints must have shape (M+1 >= 2, dim), got {W.shape}")
    if not np.all(np.isfinite(W)):
        raise InvalidProblem("waypoints must be finite")
    d = np.linalg.norm(np.diff(W, axis=0), axis=1)
    if np.any(d == 0):
        i = int(np.argmax(d == 0))
        raise InvalidProblem(f"waypoints {i} and {i + 1} coincide; a duration cannot be derived from a zero-length segment")
    return d


def constant_speed_durations(waypoints: np.ndarray, speed: float) -> np.ndarray:
    """:math:`T_i = \\|w_{i+1} - w_i\\| / v`.

    Raises
    ------
    InvalidProblem
        Non-positive speed, or two consecutive waypoints that coincide.
    """
    if not (np.isfinite(speed) and speed > 0):
        raise InvalidProblem(f"speed must be positive and finite, got {speed}")
    return _segment_lengths(waypoints) / speed


def trapezoidal_durations(waypoints: np.ndarray, v_max: float, a_max: float) -> np.ndarray:
    """Rest-to-rest trapezoidal (or triangular) velocity profile per segment (see module doc)."""
    if not (np.isfinite(v_max) and v_max > 0 and np.isfinite(a_max) and a_max > 0):
        raise InvalidProblem(f"v_max and a_max must be positive and finite, got {v_max}, {a_max}")
    d = _segment_lengths(waypoints)
    cruise = d >= v_max**2 / a_max
    return np.where(cruise, d / v_max + v_max / a_max, 2.0 * np.sqrt(d / a_max))


def stationary_time_weight(waypoints: np.ndarray, durations: np.ndarray, *, degree: int = DEFAULT_DEGREE,
                           derivative: int = DEFAULT_DERIVATIVE) -> float:
    """The time weight for which ``durations`` have the optimal total: :math:`(2q-1) J^*(T) / \\sum_i T_i`.

    At this weight :math:`F(\\alpha T)` is least at :math:`\\alpha = 1` (rest-to-rest ends;
    see the module doc), so refinement from ``durations`` only redistributes time.

    Raises
    ------
    InvalidProblem
        As :class:`~mrfswarm.trajectory.problem.MinSnapProblem`, or a degree other than ``2q - 1``.
    """
    problem = MinSnapProblem(waypoints, durations, degree=degree, derivative=derivative)
    J = cost_and_gradient(problem)[0]
    return (2 * problem.derivative - 1) * J / float(problem.durations.sum())


def scaled_time_weight(time_weight: float, alpha: float, derivative: int = DEFAULT_DERIVATIVE) -> float:
    """The weight :math:`k_T \\alpha^{-2q}` whose optimum is the ``k_T`` optimum slowed down by ``alpha``.

    Parameters
    ----------
    time_weight
        :math:`k_T` of the unscaled optimum.
    alpha
        Uniform time scale (durations multiplied by it; > 1 slows down).
    derivative
        ``q``.
    """
    return float(time_weight) * float(alpha) ** (-2 * int(derivative))


def _homogeneous(problem: MinSnapProblem) -> bool:
    """True when :math:`J^*(\\alpha T) = \\alpha^{1-2q} J^*(T)`: every given end derivative is zero."""
    return not (np.any(problem.start != 0) or np.any(problem.end != 0))


def cost_and_gradient(problem: MinSnapProblem) -> tuple[float, np.ndarray]:
    """:math:`J^*(T)` and the exact :math:`dJ^*/dT` (M,) of an equality-only problem.

    Raises
    ------
    InvalidProblem
        If the problem has a corridor or a degree other than ``2q - 1`` (the
        gradient comes from the banded closed form).
    """
    sol = solve_banded(problem, gradient=True)
    if sol.gradient is None:  # gradient=True computes it
        raise RuntimeError("solve_banded returned no gradient")
    return sol.cost, sol.gradient


@dataclass(frozen=True)
class RefinedDurations:
    """Result of :func:`refine_durations`.

    Attributes
    ----------
    durations
        (M,) refined durations.
    objective, initial_objective
        :math:`F = J^* + k_T \\sum T` at the end and at the start (with ``time_weight``).
    cost
        :math:`J^*` at the refined durations.
    time_weight
        :math:`k_T`: the one given, or (``time_weight=None``) the weight for which the
        redistributed durations are optimal.
    iterations
        Optimizer iterations.
    converged
        Whether L-BFGS-B reported convergence.
    """

    durations: np.ndarray
    objective: float
    initial_objective: float
    cost: float
    time_weight: float
    iterations: int
    converged: bool


def refine_durations(
    waypoints: np.ndarray,
    durations: np.ndarray,
    *,
    time_weight: float | None = None,
    degree: int = DEFAULT_DEGREE,
    derivative: int = DEFAULT_DERIVATIVE,
    start: EndSpec = "rest",
    end: EndSpec = "rest",
    min_duration: float | None = None,
    max_iter: int = 200,
    tol: float = 1e-9,
) -> RefinedDurations:
    """Minimize :math:`J^*(T) + k_T \\sum_i T_i` over the durations (Richter et al. 2013).

    Parameters
    ----------
    waypoints
        (M+1, dim).
    durations
        (M,) initial durations (e.g. from :func:`constant_speed_durations`).
    time_weight
        :math:`k_T > 0`, the price of one second in cost units (:math:`m^2/s^{2q-1}`).
        ``None`` keeps the total of ``durations`` and redistributes it over the pieces:
        the optimizer runs at :func:`stationary_time_weight` and its result is scaled
        back to the initial total, which is the optimum for the weight then reported in
        :attr:`RefinedDurations.time_weight` (needs ends at rest or free; see the module doc).
    degree, derivative, start, end
        As for :class:`~mrfswarm.trajectory.problem.MinSnapProblem` (degree must be ``2q - 1``).
    min_duration
        Lower bound on every duration; default ``1e-3`` times the smallest initial one.
    max_iter, tol
        L-BFGS-B iteration cap and relative tolerance on ``F``.

    Returns
    -------
    RefinedDurations

    Raises
    ------
    InvalidProblem
        A non-positive or non-finite ``time_weight`` or ``min_duration``, ``time_weight=None``
        with a non-zero end derivative, a degree other than ``2q - 1``, or malformed data.
    InvalidOptions
        ``tol`` negative or not finite.
    """
    from scipy.optimize import minimize

    if time_weight is not None and not (np.isfinite(time_weight) and time_weight > 0):
        raise InvalidProblem(f"time_weight must be positive and finite, got {time_weight}")
    if not 0 <= tol < np.inf:  # inf: one iteration, "converged" at 69 x the optimum (a library tour)
        raise InvalidOptions(f"tol must be finite and >= 0, got {tol}")
    base = MinSnapProblem(waypoints, durations, degree=degree, derivative=derivative, start=start, end=end)
    T0 = base.durations.copy()
    tmin = float(min_duration) if min_duration is not None else 1e-3 * float(T0.min())
    if not tmin > 0:
        raise InvalidProblem(f"min_duration must be positive, got {min_duration}")
    keep_total = time_weight is None
    if keep_total and not _homogeneous(base):
        raise InvalidProblem("time_weight=None (keep the total duration) needs ends at rest or free: "
                             "with a given non-zero end derivative the optimal shares depend on the weight")
    J0, _ = cost_and_gradient(base)
    q = base.derivative
    if keep_total and J0 == 0.0:  # free ends through four points: one cubic, zero cost at any durations
        return RefinedDurations(durations=T0, objective=0.0, initial_objective=0.0, cost=0.0, time_weight=0.0,
                                iterations=0, converged=True)
    weight = (2 * q - 1) * J0 / T0.sum() if time_weight is None else float(time_weight)
    F0 = J0 + weight * T0.sum()
    scale = 1.0 / F0  # the optimizer sees numbers near 1

    def fun(u: np.ndarray) -> tuple[float, np.ndarray]:
        T = np.exp(u)
        J, g = cost_and_gradient(base.with_data(durations=T))
        F = J + weight * T.sum()
        return F * scale, (g + weight) * T * scale

    u0 = np.log(np.maximum(T0, tmin))
    res = minimize(fun, u0, jac=True, method="L-BFGS-B", bounds=[(np.log(tmin), None)] * T0.size,
                   options=dict(maxiter=max_iter, ftol=tol, gtol=1e-10))
    T = np.exp(res.x)
    if keep_total:
        alpha = T0.sum() / T.sum()
        T = T * alpha
        weight = scaled_time_weight(weight, alpha, q)
        F0 = J0 + weight * T0.sum()
    J, _ = cost_and_gradient(base.with_data(durations=T))
    log.info("duration refinement: F %.6g -> %.6g in %d iterations (%s)", F0, J + weight * T.sum(), res.nit, res.message)
    return RefinedDurations(durations=T, objective=J + weight * T.sum(), initial_objective=F0, cost=J,
                            time_weight=float(weight), iterations=int(res.nit), converged=bool(res.success))
