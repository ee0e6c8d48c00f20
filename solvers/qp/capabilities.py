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
    iteration_cap
        The backend caps ``Options.max_iter`` at this many iterations (interior-point
        methods converge in tens); None: it runs ``Options.max_iter``. A caller that gives
        a solve a share of the budget computes it from the smaller of the two
        (:meth:`iteration_budget`).
    """

    inequalities: bool
    warm_start: bool
    detects_infeasibility: bool
    sparse: bool
    nlp: bool = False
    iteration_cap: int | None = None

    def __post_init__(self) -> None:
        # a cap of 0 gave every attempt a budget of one iteration: a tour's record flew the corridor in 27.9 s instead
        # of 20.5, without a word (the warning on failed attempts is for backends without a cap)
        cap = self.iteration_cap
        if cap is not None and (isinstance(cap, bool) or not isinstance(cap, int) or cap < 1):
            raise ValueError(f"QPCapabilities.iteration_cap = {cap!r}: must be None (no cap) or a whole number >= 1")

    def iteration_budget(self, max_iter: int) -> int:
        """The iterations a solve given ``max_iter`` runs at most."""
        return max_iter if self.iteration_cap is None else min(max_iter, self.iteration_cap)

    def flags(self) -> list[str]:
        """The names of the capabilities the backend has, for listings."""
        return [name if on is True else f"{name}={on}" for name, on in vars(self).items() if on]
