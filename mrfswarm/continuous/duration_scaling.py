r"""A handful of QP solves that shorten a window's step durations: the multiplier scaling.

The time refinement's objective over a window's step durations T is
:math:`f(T) = J^*(T) + w \sum_j T_j`, with :math:`J^*` the window problem's optimal cost
(the integral of the squared q-th derivative) and its exact gradient from the QP's
multipliers (:meth:`~mrfswarm.continuous.receding_horizon.RecedingHorizon.time_allocation`).
Stretching a flight in time by :math:`\alpha` divides its q-th derivative by
:math:`\alpha^q`, so the cost of each piece scales as :math:`T_j^{1 - 2q}`. Modelling each
step on its own as :math:`c_j T_j^{1-2q} + w T_j` and reading :math:`c_j` off the gradient
:math:`g_j = \partial J^* / \partial T_j` gives the model's minimizer in closed form:

.. math::

    T_j \leftarrow T_j \left( \frac{-g_j}{w} \right)^{1/(2q)}

Steps whose multipliers press (large :math:`-g_j`: a limit or a corridor binds, the
flight is stiff) get longer, the others shorter. Each iteration is one QP solve (value and
gradient together); a step that leaves the problem infeasible or raises f is halved in
the logarithm, at most ``backtracks`` times. Every per-step factor is kept within
``[clip, 1 / clip]`` per iteration, so the model is used only near where it was read.
When the very first step finds no feasible lower point, it is tried once more with the
window's first step held: the window starts in a given state (speed, acceleration), which
pins its first step from both sides (a fast robot overshoots its region if that step is
longer, and cannot reach far enough if it is shorter). On the 40 robots in clutter of
the flight-quality bench, 8 windows of 23 stayed blocked instead of 11 (makespan 76.4 s to 68.5).

Why not the NLP backends alone: Ipopt on the same problem evaluated 73 points per window
on the forest (12 iterations, infeasible trial points and all); this evaluates 2 to 7
per window on average (trap 2.9, forest 4.6, clutter 6.9, capped at the window's sum, see
``total``) and stops when an
iteration gains less than ``tol``. Measured with ``experiments/bench/flight_quality.py``
(see the README): its makespans were within 1 to 8 % of Ipopt's (clutter 69.2 s against
62.7, forest 28.0 against 26.0) at a fifth to a seventh of its planning time; capped,
clutter 64.8 s, forest 26.3.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from solvers.nlp import NLPProblem

#: Iterations at most (each one QP solve, plus its backtracks; the retry with the first step held counts as one).
ITERATIONS = 8
#: Per-iteration bound of each step's factor: within [CLIP, 1 / CLIP].
CLIP = 0.8
#: Halvings (in the logarithm) of a step that fails, before the iteration stops. With the windows' sum capped
#: (``total``), 1 flew the flight-quality maps as 2 did or sooner (clutter40 69.8 -> 64.8 s, forest 26.7 -> 26.3)
#: with a quarter to a half fewer QP solves (clutter40 220 -> 158 evaluations, forest 60 -> 46, trap 57 -> 29);
#: 0 saved a fifth more and flew aisles30 3.5 % and the doorway 2 % later (one run each).
BACKTRACKS = 1
#: Relative gain in f below which an iteration is the last (0.03 saved few solves more and stopped 0.7 % above
#: Ipopt's optimum of the passing window, test_duration_scaling).
TOL = 0.01


@dataclass(frozen=True)
class ScalingResult:
    """What :func:`scale_durations` reached.

    Attributes
    ----------
    x
        The last accepted durations (the start point if none was).
    value
        f there.
    iterations
        Accepted iterations.
    evaluations
        Points evaluated (QP solves, each with its gradient).
    status
        Why it stopped: ``"converged"`` (gain below tol, or no lower point along the step),
        ``"max_iter"``, ``"blocked"`` (the step and its backtracks without lower feasible point, some
        infeasible) or ``"infeasible start"``.
    """

    x: np.ndarray
    value: float
    iterations: int
    evaluations: int
    status: str


def step_factors(g: np.ndarray, weight: float, derivative: int, clip: float = CLIP) -> np.ndarray:
    """Each step's factor in one iteration of the scaling: :math:`(-g_j / w)^{1/(2q)}` within [clip, 1 / clip],
    ``g`` being dJ*/dT (the gradient of f less the weight)."""
    return np.clip((np.maximum(-np.asarray(g, dtype=float), 1e-300) / weight) ** (1.0 / (2 * derivative)), clip,
                   1.0 / clip)


def scale_durations(problem: NLPProblem, weight: float, derivative: int, iterations: int = ITERATIONS,
                    clip: float = CLIP, backtracks: int = BACKTRACKS, tol: float = TOL,
                    total: float | None = None) -> ScalingResult:
    """Shorten the durations of ``problem`` (f = J* + ``weight`` sum T, its gradient exact) by the multiplier
    scaling above, starting at ``problem.x0``; ``derivative`` is q of the cost.

    With ``total``, no point evaluated lasts longer in sum: a step of the scaling that
    would is scaled down, all its steps by one factor (the held first step excepted), to
    last ``total``, so it still moves time from the steps that cost little to those that
    press. The window refinement passes the QP's own durations, as it keeps no point that
    lasts longer than them: without the cap it kept nothing in 3 of 11 windows of the
    rooms map and 8 of 10 of the trap (with it 1 and 3), spending their solves on longer
    points.

    f and its gradient may be NaN where the window has no solution; such a point is never
    accepted.
    """
    if not (0 < clip < 1):
        raise ValueError(f"clip must be in (0, 1), got {clip}")
    if weight <= 0:
        raise ValueError(f"weight must be > 0, got {weight}")
    T = np.asarray(problem.x0, dtype=float).copy()
    lo = np.broadcast_to(np.asarray(problem.lower, dtype=float), T.shape)
    hi = np.broadcast_to(np.asarray(problem.upper, dtype=float), T.shape)
    f = float(problem.fun(T))
    evaluations = 1
    if not np.isfinite(f):
        return ScalingResult(T, f, 0, evaluations, "infeasible start")
    done, tries, hold = 0, 0, 0
    while tries < iterations:
        tries += 1
        g = np.asarray(problem.grad(T), dtype=float) - weight  # dJ*/dT
        if not np.all(np.isfinite(g)):
            return ScalingResult(T, f, done, evaluations, "blocked")
        log_ratio = np.log(step_factors(g, weight, derivative, clip))
        log_ratio[:hold] = 0.0
        if np.abs(log_ratio).max() < 1e-12:  # the model's minimizer
            return ScalingResult(T, f, done, evaluations, "converged")
        infeasible = False
        for _ in range(backtracks + 1):
            trial = np.clip(T * np.exp(log_ratio), lo, hi)
            if total is not None and trial.sum() > total:
                rest = trial[hold:].sum()
                trial[hold:] = np.clip(trial[hold:] * (total - trial[:hold].sum()) / rest, lo[hold:], hi[hold:])
            f_trial = float(problem.fun(trial))
            evaluations += 1
            if np.isfinite(f_trial) and f_trial < f:
                break
            infeasible |= not np.isfinite(f_trial)
            log_ratio = 0.5 * log_ratio
        else:  # no lower point along the step: infeasible trials, or a minimum along it
            if infeasible and done == 0 and hold == 0 and len(T) > 1:
                hold = 1
                continue
            return ScalingResult(T, f, done, evaluations, "blocked" if infeasible else "converged")
        gain = (f - f_trial) / max(abs(f), 1e-300)
        T, f, done = trial, f_trial, done + 1
        if gain < tol:
            return ScalingResult(T, f, done, evaluations, "converged")
    return ScalingResult(T, f, done, evaluations, "max_iter")
