"""The best feasible labelling seen so far, for methods whose iterates are not monotone.

Loopy BP, TRW-S and Gibbs sampling produce a candidate labelling per iteration whose
energy goes up as well as down, and BP's and TRW-S's candidates may break a conflict.
:class:`Incumbent` repairs each infeasible candidate with :func:`~solvers.mrf.problem.repair`
(and counts it), and keeps the feasible labelling of least energy, starting from
``mrf.initial``; so these methods never return a labelling worse than ``initial``.
:meth:`Incumbent.result` turns it into the method's :class:`~solvers.mrf.result.MRFResult`,
finished with ICM when ``Options.polish`` asks for it (the one place the three methods
share that step).
"""

from __future__ import annotations

import time

import numpy as np

from solvers.mrf.icm import descend
from solvers.mrf.local_energy import LocalEnergy, colour_sweep
from solvers.mrf.problem import PairwiseMRF, repair
from solvers.mrf.result import MRFResult, Options


class Incumbent:
    """Best feasible labelling so far, starting from ``mrf.initial``.

    Attributes
    ----------
    labels, energy
        The incumbent.
    repaired
        Nodes that :func:`repair` sent back in the candidate that became the incumbent.
    repairs
        Candidates offered that needed repair.
    repaired_nodes
        Nodes sent back over all offered candidates.
    """

    def __init__(self, mrf: PairwiseMRF) -> None:
        self.mrf = mrf
        self.labels = mrf.initial.copy()
        self.energy = mrf.energy(self.labels)
        self.repaired = 0
        self.repairs = 0
        self.repaired_nodes = 0

    def offer(self, x: np.ndarray) -> float:
        """Consider the candidate ``x`` (repaired first if infeasible); return its (repaired) energy."""
        n = 0
        if not self.mrf.is_feasible(x):
            x, n = repair(self.mrf, x)
            self.repairs += 1
            self.repaired_nodes += n
        e = self.mrf.energy(x)
        if e < self.energy:
            self.labels, self.energy, self.repaired = np.array(x, dtype=np.intp, copy=True), e, n
        return e

    def stats(self) -> dict:
        """The repair counts, for ``MRFResult.stats``."""
        return {"repairs": self.repairs, "repaired_nodes": self.repaired_nodes}

    def result(self, method: str, options: Options, trace: list[float], iterations: int, t_start: float,
               deadline: float | None, stats: dict, *, sweep: list[LocalEnergy] | None = None,
               lower_bound: float | None = None) -> MRFResult:
        """The method's result: the incumbent, polished by ICM if ``options.polish``.

        Parameters
        ----------
        method
            The registry name.
        options
            The method's options (``polish``, and ``max_iter``, ``tol`` for the ICM descent).
        trace
            The incumbent's energy after each iteration; the polished energy is appended.
        iterations
            Iterations the method ran.
        t_start
            ``time.perf_counter()`` when the method started.
        deadline
            The ``perf_counter`` time limit of the polish descent, or None.
        stats
            Method-specific numbers; ``initial_energy``, the repair counts and (when
            polishing) ``polish_moves`` are added.
        sweep
            The colour sweep for the ICM descent, if the method already built it.
        lower_bound
            A lower bound on the optimum, if the method has one.
        """
        labels, energy = self.labels, self.energy
        trace = list(trace)
        stats = {**stats, "initial_energy": self.mrf.energy(self.mrf.initial), **self.stats()}
        if options.polish:
            sweep = colour_sweep(self.mrf) if sweep is None else sweep
            labels, ptrace, moves = descend(self.mrf, labels, sweep, options.max_iter, options.tol, deadline)
            energy = ptrace[-1]
            trace.append(energy)
            stats["polish_moves"] = moves
        return MRFResult(
            labels=labels,
            energy=energy,
            energy_trace=np.array(trace),
            iterations=iterations,
            time_s=time.perf_counter() - t_start,
            method=method,
            lower_bound=lower_bound,
            repaired=self.repaired,
            stats=stats,
        )
