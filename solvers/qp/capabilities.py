"""What a QP backend can do: one typed record per backend, read by dispatch."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True, kw_only=True)
class QPCapabilities:
    """The capabilities of a QP backend; every backend states each one.

    Attributes
    ----------
    inequalities
        Accepts rows with ``l < u``. Without it the backend solves equality-constrained
        problems only, and :func:`solvers.qp.prepare` refuses any other.
    warm_start
        Starts from a given primal point. A backend without it accepts
        ``solve(warm_start=x)`` and ignores the point (interior-point and direct
        methods), so callers do not pass one.
    detects_infeasibility
        Reports an infeasible problem as :class:`~solvers.errors.InfeasibleError`;
        without it an infeasible problem ends in another :class:`~solvers.errors.SolverError`
        (an iteration cap).
    sparse
        Sparse linear algebra: suits thousands of variables. A dense backend is fine
        for one robot's window and slow above a few hundred variables.
    nlp
        The same engine also solves general nonlinear programs (see
        :func:`solvers.qp.ipopt_.solve_nlp`, and the NLP backend of the same name in
        :data:`solvers.nlp.BACKENDS`).
    """

    inequalities: bool
    warm_start: bool
    detects_infeasibility: bool
    sparse: bool
    nlp: bool = False

    def flags(self) -> list[str]:
        """The names of the capabilities the backend has, for listings."""
        return [name for name, on in vars(self).items() if on]
