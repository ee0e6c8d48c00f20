"""The problem's callables as every backend calls them: counted, checked, remembered.

Dispatch hands each backend a copy of the problem whose ``fun`` and ``grad`` are an
:class:`Evaluations`' methods, so that evaluations are counted the same way for every
backend, a gradient of the wrong shape is an :class:`~solvers.errors.InvalidProblem`
whichever backend asked for it, and an exception raised by the user's callable reaches
the caller as itself even through a native backend (CasADi turns it into its own
``RuntimeError``; dispatch re-raises the original).

NaN: ``f`` may be NaN where it cannot be evaluated. A backend whose record has
``nan_step_back`` (Ipopt) sees the NaN and shortens its step itself. The others would
stop at the first NaN (L-BFGS-B's line search ends "abnormal", sqpmethod's sensitivities
become irregular), so they see instead a value above every finite one seen so far (and the last finite
gradient there, which a line search or a trust region never uses: it steps back, as Ipopt
does).
The returned :class:`~solvers.nlp.Solution` still reports ``f``'s own value. A point where the gradient was
not finite is never reported optimal either (four backends stopped at the start of a problem whose gradient was
NaN there and called it optimal: they had been handed zeros).
"""

from __future__ import annotations

import numpy as np

from solvers.errors import InvalidProblem, SolverError, real_array
from solvers.nlp.problem import NLPProblem


def _number(value: object) -> float:
    """``f``'s value as a float: one real number (a NumPy scalar or an array of one element too), else
    InvalidProblem naming it (an array of two values ended in NumPy's "only 0-dimensional arrays can be converted
    to Python scalars", a string in "could not convert string to float", naming no callable; a library tour)."""
    if isinstance(value, (float, int)):
        return float(value)
    try:
        a = real_array(value, "fun's value")
    except InvalidProblem:
        a = None
    if a is None or a.size != 1:
        shown = " ".join(repr(value).split())
        raise InvalidProblem(f"fun returned {shown:.60}: must be one real number")
    return float(a.reshape(()))


class Evaluations:
    """Counting wrappers of ``problem.fun`` and ``problem.grad``.

    Attributes
    ----------
    fun_calls, grad_calls
        How many times each was called.
    raised
        The first exception a callable (or a check here) raised, if any.
    """

    def __init__(self, problem: NLPProblem, *, replace_nan: bool = False, inside: str | None = None) -> None:
        self.problem = problem
        self.replace_nan = replace_nan
        #: the backend whose record promises to evaluate only inside the bounds (``bounds``), if any
        self.inside = inside
        self.highest = -np.inf
        self._last_gradient: np.ndarray | None = None
        self.fun_calls = 0
        self.grad_calls = 0
        self.raised: BaseException | None = None
        self._values: dict[bytes, float] = {}
        #: (f, x) of the lowest finite value evaluated, wherever it was (dispatch hands it back, if it meets the
        #: bounds and rows, to a run that ended where f is not finite)
        self.best: tuple[float, np.ndarray] | None = None
        #: x -> whether the user's gradient there was finite (a NaN gradient handed on as zeros looked stationary)
        self._finite_gradient: dict[bytes, bool] = {}

    def _check_inside(self, x: np.ndarray, what: str) -> None:
        """A :class:`SolverError` naming the backend if its record promises ``bounds`` and ``x`` is outside them: a
        tour's backend stepping past them handed the time refinement negative durations, and the run stopped with
        "P[4, 4] = -1.1e+16 < 0: P must be positive semidefinite", naming neither the backend nor the bounds."""
        if self.inside is None or x.size != self.problem.n:
            return
        lower, upper = np.asarray(self.problem.lower), np.asarray(self.problem.upper)
        out = np.flatnonzero((x < lower) | (x > upper))
        if out.size:
            i = int(out[0])
            raise SolverError(f"{self.inside}: evaluated {what} at x[{i}] = {x[i]:.6g}, outside its bounds "
                              f"[{lower[i]:.6g}, {upper[i]:.6g}], although its record claims bounds",
                              backend=self.inside, status="outside the bounds")

    def fun(self, x: np.ndarray) -> float:
        """``f(x)``, counted and remembered."""
        self.fun_calls += 1
        x = np.array(x, dtype=float).reshape(-1)
        try:
            self._check_inside(x, "f")
            value = _number(self.problem.fun(x))
        except BaseException as e:
            self.raised = self.raised or e
            raise
        self._values[x.tobytes()] = value
        if np.isfinite(value) and (self.best is None or value < self.best[0]):
            self.best = (value, x.copy())
        if np.isnan(value) and self.replace_nan:
            return self.step_back_value()
        if np.isfinite(value):
            self.highest = max(self.highest, value)
        return value

    def step_back_value(self) -> float:
        """What a backend without ``nan_step_back`` sees for NaN: above every finite value seen."""
        if not np.isfinite(self.highest):
            return 1e150  # nothing finite seen yet: any finite value will look better
        return self.highest + max(1.0, abs(self.highest))

    def grad(self, x: np.ndarray) -> np.ndarray:
        """``grad f(x)`` as a float vector of shape (n,), counted."""
        self.grad_calls += 1
        x = np.array(x, dtype=float).reshape(-1)
        try:
            self._check_inside(x, "the gradient")
            g = real_array(self.problem.grad(x), "grad's value")
            if g.size != x.size:
                raise InvalidProblem(f"grad returned {g.size} entries, the problem has {x.size} variables")
        except BaseException as e:
            self.raised = self.raised or e
            raise
        self._finite_gradient[x.tobytes()] = bool(np.all(np.isfinite(g)))
        if self.replace_nan:
            if np.any(np.isnan(g)):
                return np.zeros(x.size) if self._last_gradient is None else self._last_gradient.copy()
            self._last_gradient = g.reshape(-1).copy()
        return g.reshape(-1)

    def gradient_finite_at(self, x: np.ndarray) -> bool | None:
        """Whether the gradient evaluated at exactly ``x`` was finite; None if it was not evaluated there."""
        return self._finite_gradient.get(np.asarray(x, dtype=float).reshape(-1).tobytes())

    def value_at(self, x: np.ndarray) -> float:
        """``f(x)``: the value already computed at exactly ``x``, else one more (uncounted) call; NaN, without a
        call, at a point that is not finite (a backend's answer: the user's ``f`` is never handed one, and a time
        refinement's raised "P, q and A must be finite", naming neither the backend nor its NaN point)."""
        x = np.asarray(x, dtype=float).reshape(-1)
        if not np.all(np.isfinite(x)):
            return float("nan")
        known = self._values.get(x.tobytes())
        return float(self.problem.fun(x.copy())) if known is None else known

    def counted(self) -> NLPProblem:
        """The problem with these wrappers as its callables."""
        return self.problem.with_functions(self.fun, self.grad)
