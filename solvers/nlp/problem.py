"""The one problem form every NLP backend receives.

.. math::

    \\min_x f(x) \\quad \\text{s.t.} \\quad \\ell \\le x \\le u, \\qquad
    l_A \\le A x \\le u_A

with ``f`` smooth and given by two Python callables, its value and its gradient (an
objective that is itself the optimal value of an inner problem, say, whose gradient comes
from the envelope theorem). Bounds may be infinite; the linear rows are optional (``A``
with no rows). A row with ``l_A == u_A`` is an equality. Shapes, finiteness and the start
point are checked once, at construction, so backends never see a malformed problem.

``f`` may return NaN at a point where it cannot be evaluated (an inner problem without a
solution there); what a backend does with it is its record's ``nan_step_back``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from solvers.errors import InvalidProblem, real_array

#: Slack, relative to the bound's size, within which the start point counts as inside its bounds.
START_SLACK = 1e-12


@dataclass(frozen=True, eq=False)
class NLPProblem:
    """A validated, bound- (and optionally linearly) constrained smooth minimization.

    Parameters
    ----------
    fun
        ``f(x) -> float`` for ``x`` of shape (n,).
    grad
        ``grad f(x) -> (n,)``.
    x0
        (n,) start point, finite and within ``lower``/``upper``.
    lower, upper
        (n,) bounds (scalars broadcast); ``-inf``/``inf`` for a free side. Default free.
    A
        (m, n) dense matrix of linear rows; ``None`` for none.
    lb, ub
        (m,) bounds of ``A x``; ``-inf``/``inf`` allowed, ``lb <= ub``.
    """

    fun: Callable[[np.ndarray], float]
    grad: Callable[[np.ndarray], np.ndarray]
    x0: np.ndarray
    lower: np.ndarray | float = -np.inf
    upper: np.ndarray | float = np.inf
    A: np.ndarray | None = None
    lb: np.ndarray | float = -np.inf
    ub: np.ndarray | float = np.inf

    def __post_init__(self) -> None:
        if not (callable(self.fun) and callable(self.grad)):
            raise InvalidProblem("fun and grad must be callables")
        x0 = real_array(self.x0, "x0").reshape(-1)
        n = x0.size
        if n == 0:
            raise InvalidProblem("the problem has no variables (x0 is empty)")
        lower = _vector("lower", self.lower, n)
        upper = _vector("upper", self.upper, n)
        A = np.zeros((0, n)) if self.A is None else real_array(self.A, "A")
        if A.ndim != 2 or A.shape[1] != n:
            raise InvalidProblem(f"A has shape {A.shape}, expected (m, {n})")
        if not np.all(np.isfinite(A)):
            raise InvalidProblem("A must be finite (found NaN or inf)")
        m = A.shape[0]
        lb = _vector("lb", self.lb, m)
        ub = _vector("ub", self.ub, m)
        if not np.all(np.isfinite(x0)):
            raise InvalidProblem("x0 must be finite")
        for name, lo, hi in (("", lower, upper), ("A x: ", lb, ub)):
            if np.any(lo > hi):
                i = int(np.argmax(lo > hi))
                raise InvalidProblem(f"{name}lower[{i}] = {lo[i]} > upper[{i}] = {hi[i]}")
            if np.any(lo == np.inf) or np.any(hi == -np.inf):  # no x meets such a bound
                i = int(np.argmax((lo == np.inf) | (hi == -np.inf)))
                raise InvalidProblem(f"{name}lower[{i}] = {lo[i]}, upper[{i}] = {hi[i]}: no x meets it")
        slack = START_SLACK * np.maximum(1.0, np.abs(x0))
        outside = (x0 < lower - slack) | (x0 > upper + slack)
        if np.any(outside):
            i = int(np.argmax(outside))
            raise InvalidProblem(f"x0[{i}] = {x0[i]} is outside its bounds [{lower[i]}, {upper[i]}]")
        object.__setattr__(self, "x0", np.clip(x0, lower, upper))
        object.__setattr__(self, "lower", lower)
        object.__setattr__(self, "upper", upper)
        object.__setattr__(self, "A", A)
        object.__setattr__(self, "lb", lb)
        object.__setattr__(self, "ub", ub)

    @property
    def n(self) -> int:
        """Number of variables."""
        return int(self.x0.size)

    @property
    def m(self) -> int:
        """Number of linear rows."""
        return int(self.rows.shape[0])

    @property
    def rows(self) -> np.ndarray:
        """``A`` as the (m, n) array it is after construction (m = 0 without rows)."""
        return np.asarray(self.A)

    @property
    def has_linear_rows(self) -> bool:
        """True if some linear row constrains ``x`` (a row free on both sides does not)."""
        return bool(np.any(np.isfinite(self.lb) | np.isfinite(self.ub)))

    def max_violation(self, x: np.ndarray) -> float:
        """The largest violation of the bounds and the linear rows at ``x`` (0 when feasible)."""
        x = np.asarray(x, dtype=float)
        v = max(np.max(self.lower - x, initial=0.0), np.max(x - self.upper, initial=0.0))
        if self.m:
            ax = self.rows @ x
            v = max(v, np.max(self.lb - ax, initial=0.0), np.max(ax - self.ub, initial=0.0))
        return float(v)

    def with_functions(self, fun: Callable[[np.ndarray], float], grad: Callable[[np.ndarray], np.ndarray]) -> NLPProblem:
        """The same problem with other callables (dispatch's counting wrappers)."""
        return dataclasses.replace(self, fun=fun, grad=grad)


def _vector(name: str, value, size: int) -> np.ndarray:
    v = real_array(value, name)
    v = np.array(np.broadcast_to(v, (size,)) if v.ndim == 0 else v).reshape(-1)
    if v.size != size:
        raise InvalidProblem(f"{name} has {v.size} entries, expected {size}")
    if np.any(np.isnan(v)):
        raise InvalidProblem(f"{name} must not contain NaN")
    return v
