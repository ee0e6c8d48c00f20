"""What an NLP backend can do: one typed record per backend, read by dispatch and tests."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True, kw_only=True)
class NLPCapabilities:
    """The capabilities of an NLP backend; every backend states each one.

    Attributes
    ----------
    bounds
        Takes variable bounds and never evaluates ``f`` outside them (the time
        refinement's durations must stay positive): dispatch stops a backend that does with a
        ``SolverError`` naming it; without it :func:`solvers.nlp.minimize` refuses a problem
        with finite bounds.
    linear_constraints
        Takes linear rows ``lb <= A x <= ub``; without it :func:`solvers.nlp.minimize`
        refuses a problem that has some.
    needs_gradient
        Calls the problem's gradient callable (no finite differences of ``f``).
    quasi_newton
        Uses second-order information from a quasi-Newton approximation built from
        gradients (BFGS or limited-memory BFGS); no Hessian callable is needed.
    nan_step_back
        Treats a NaN value of ``f`` as "cannot evaluate here" and shortens its step, so
        ``f`` may be undefined on part of the box (checked by the tests).
    time_limit_native
        Checks ``Options.time_limit`` inside an iteration; without it the limit is
        checked between iterations.
    """

    bounds: bool
    linear_constraints: bool
    needs_gradient: bool
    quasi_newton: bool
    nan_step_back: bool
    time_limit_native: bool

    def flags(self) -> list[str]:
        """The names of the capabilities the backend has, for listings."""
        return [name for name, on in vars(self).items() if on]
