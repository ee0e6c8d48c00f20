"""The best feasible labelling seen so far, for methods whose iterates are not monotone.

Loopy BP, TRW-S and Gibbs sampling produce a candidate labelling per iteration whose
energy goes up as well as down, and BP's and TRW-S's candidates may break a conflict.
:class:`Incumbent` repairs each infeasible candidate with :func:`~solvers.mrf.problem.repair`
(and counts it), and keeps the feasible labelling of least energy, starting from
``mrf.initial``; so these methods never return a labelling worse than ``initial``.
"""

from __future__ import annotations

import numpy as np

from solvers.mrf.problem import PairwiseMRF, repair


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
