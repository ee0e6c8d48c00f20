"""Sequential tree-reweighted message passing (TRW-S), with its lower bound.

Kolmogorov, V. (2006). "Convergent tree-reweighted message passing for energy
minimization". IEEE Trans. PAMI 28(10), 1568–1583.

The model is :func:`~solvers.mrf.penalized.penalized_pairs` (edges plus conflict pairs,
forbidden label pairs costing the finite ``Options.conflict_penalty``). Nodes are
ordered by the colour classes of the union graph (nodes of one class share no pair, so
processing a class in one array expression is exactly processing its nodes one after
another), and every pair is oriented from its earlier to its later node. The graph is
covered by monotonic chains; node i lies on n_i = max(#earlier, #later neighbours, 1)
of them and gets weight gamma_i = 1/n_i. One iteration is a forward pass over the
classes, then a backward pass over them in reverse; processing node i in the forward
pass sets

.. math::

    \\hat\\theta_i = U_i + \\sum_{j} m_{j \\to i}, \\qquad
    m_{i \\to j}(b) = \\min_a \\big[\\gamma_i \\hat\\theta_i(a) - m_{j \\to i}(a) + W_{ij}(a, b)\\big] - \\delta_{ij}

for every later neighbour j (delta_ij normalizes the message to min 0), and the backward
pass does the same towards the earlier neighbours.

Lower bound. After a forward pass every forward message is consistent with the current
hat-theta, so the minimum of each chain's energy follows by dynamic programming along
the chain, and the sum over chains (the TRW bound of the current reparametrization) is

.. math::

    \\Phi = \\sum_{(i,j)} \\delta_{ij} + \\sum_i \\Big(1 - \\frac{n^{out}_i}{n_i}\\Big) \\min_a \\hat\\theta_i(a)

(chains end at node i n_i - n^out_i times); after a backward pass the same with the
backward deltas and n^in_i. Kolmogorov proves it never decreases; ``lower_bound`` is the
largest seen. It bounds the minimum of the penalized energy E_P without the conflicts as
constraints, which is at most the constrained optimum (E_P = E on feasible labellings),
hence a valid lower bound of the problem actually posed, for any penalty >= 0.

Decoding, as in the paper: in the forward order, x_i minimizes U_i(a) + sum over earlier
neighbours of W(x_j, a) + sum over later neighbours of m_{j->i}(a), among the labels that
break no conflict with the earlier nodes already decoded (unrestricted if none is left,
in which case the decoding is repaired, counted in ``MRFResult.repaired`` and
``stats["repairs"]``). The best feasible decoding (or ``initial``) is returned.

Stops when the best energy meets the bound (up to ``Options.tol``), when an iteration
raises the bound by at most ``Options.tol * max(1, |bound|)``, after ``Options.max_iter``
iterations or at ``Options.time_limit``. On a tree without conflicts the bound reaches
the optimum and the decoding is optimal. With ``Options.polish`` the result is finished
with ICM.
"""

from __future__ import annotations

import time

import numpy as np

from solvers.mrf.capabilities import MRFCapabilities
from solvers.mrf.incumbent import Incumbent
from solvers.mrf.local_energy import colour_classes
from solvers.mrf.penalized import auto_penalty, penalized_pairs
from solvers.mrf.problem import PairwiseMRF
from solvers.mrf.result import MRFResult, Options
from solvers.registry import Backend


class _Chains:
    """The ordered, oriented model and per-class index arrays of TRW-S."""

    def __init__(self, mrf: PairwiseMRF, penalty: float) -> None:
        N, L = mrf.n_nodes, mrf.max_labels
        self.L = L
        self.classes = colour_classes(mrf)
        rank = np.empty(N, dtype=np.intp)
        for c, nodes in enumerate(self.classes):
            rank[nodes] = c
        pairs, tables = penalized_pairs(mrf, penalty)
        swap = rank[pairs[:, 0]] > rank[pairs[:, 1]]
        self.first = np.where(swap, pairs[:, 1], pairs[:, 0])
        self.second = np.where(swap, pairs[:, 0], pairs[:, 1])
        self.tables = np.where(swap[:, None, None], tables.transpose(0, 2, 1), tables)
        self.P = len(pairs)
        self.n_out = np.bincount(self.first, minlength=N)
        self.n_in = np.bincount(self.second, minlength=N)
        self.gamma = 1.0 / np.maximum(np.maximum(self.n_out, self.n_in), 1)
        self.unary = mrf.unary
        pos = np.empty(N, dtype=np.intp)
        for nodes in self.classes:
            pos[nodes] = np.arange(nodes.size)
        lab = np.arange(L)
        by_first = [np.flatnonzero(rank[self.first] == c) for c in range(len(self.classes))]
        by_second = [np.flatnonzero(rank[self.second] == c) for c in range(len(self.classes))]
        # per class: pairs leaving it forward (first in class), pairs entering it (second in class),
        # with the flat scatter positions of their rows into the class's (S, L) array
        self.out_pairs = by_first
        self.in_pairs = by_second
        self.out_pos = [pos[self.first[p]] for p in by_first]
        self.in_pos = [pos[self.second[p]] for p in by_second]
        self.out_flat = [(q[:, None] * L + lab).ravel() for q in self.out_pos]
        self.in_flat = [(q[:, None] * L + lab).ravel() for q in self.in_pos]
        # hard conflicts oriented by rank, grouped by the class of the later node (for decoding)
        conf = mrf.conflicts
        cswap = rank[conf[:, 0]] > rank[conf[:, 1]] if len(conf) else np.zeros(0, bool)
        self.c_early = np.where(cswap, conf[:, 1], conf[:, 0]) if len(conf) else np.zeros(0, np.intp)
        c_late = np.where(cswap, conf[:, 0], conf[:, 1]) if len(conf) else np.zeros(0, np.intp)
        self.c_mask = np.where(cswap[:, None, None], mrf.conflict_mask.transpose(0, 2, 1), mrf.conflict_mask)
        self.conf_in = [np.flatnonzero(rank[c_late] == c) for c in range(len(self.classes))]
        self.conf_flat = [(pos[c_late[q]][:, None] * L + lab).ravel() for q in self.conf_in]

    def theta_hat(self, c: int, fw: np.ndarray, bw: np.ndarray) -> np.ndarray:
        """(S, L) U_i + all incoming messages, for the nodes of class c."""
        nodes = self.classes[c]
        out = self.unary[nodes].copy()
        flat, size = out.reshape(-1), out.size
        if self.in_pairs[c].size:
            flat += np.bincount(self.in_flat[c], weights=fw[self.in_pairs[c]].ravel(), minlength=size)
        if self.out_pairs[c].size:
            flat += np.bincount(self.out_flat[c], weights=bw[self.out_pairs[c]].ravel(), minlength=size)
        return out

    def theta_hat_all(self, fw: np.ndarray, bw: np.ndarray) -> np.ndarray:
        N, L = self.unary.shape
        lab = np.arange(L)
        th = self.unary.copy()
        if self.P:
            th += np.bincount((self.second[:, None] * L + lab).ravel(), weights=fw.ravel(),
                              minlength=N * L).reshape(N, L)
            th += np.bincount((self.first[:, None] * L + lab).ravel(), weights=bw.ravel(),
                              minlength=N * L).reshape(N, L)
        return th

    def forward(self, fw: np.ndarray, bw: np.ndarray, delta: np.ndarray) -> None:
        for c in range(len(self.classes)):
            p = self.out_pairs[c]
            if not p.size:
                continue
            th = self.theta_hat(c, fw, bw)
            h = self.gamma[self.first[p], None] * th[self.out_pos[c]] - bw[p]
            new = (h[:, :, None] + self.tables[p]).min(axis=1)
            d = new.min(axis=1)
            fw[p] = new - d[:, None]
            delta[p] = d

    def backward(self, fw: np.ndarray, bw: np.ndarray, delta: np.ndarray) -> None:
        for c in range(len(self.classes) - 1, -1, -1):
            p = self.in_pairs[c]
            if not p.size:
                continue
            th = self.theta_hat(c, fw, bw)
            h = self.gamma[self.second[p], None] * th[self.in_pos[c]] - fw[p]
            new = (h[:, None, :] + self.tables[p]).min(axis=2)
            d = new.min(axis=1)
            bw[p] = new - d[:, None]
            delta[p] = d

    def bound(self, fw: np.ndarray, bw: np.ndarray, delta: np.ndarray, n_continue: np.ndarray) -> float:
        """Sum of the chains' minima right after a pass whose messages' deltas are ``delta``."""
        th = self.theta_hat_all(fw, bw)
        n = np.maximum(np.maximum(self.n_out, self.n_in), 1)
        return float(delta.sum() + ((1.0 - n_continue / n) * th.min(axis=1)).sum())

    def decode(self, fw: np.ndarray, bw: np.ndarray) -> np.ndarray:
        """Forward-order decoding: earlier neighbours fixed, later ones through their messages."""
        x = np.zeros(self.unary.shape[0], dtype=np.intp)
        L = self.L
        for c, nodes in enumerate(self.classes):
            cost = self.unary[nodes].copy()
            flat = cost.reshape(-1)
            p = self.in_pairs[c]
            if p.size:
                flat += np.bincount(self.in_flat[c], weights=self.tables[p, x[self.first[p]], :].ravel(),
                                    minlength=flat.size)
            p = self.out_pairs[c]
            if p.size:
                flat += np.bincount(self.out_flat[c], weights=bw[p].ravel(), minlength=flat.size)
            q = self.conf_in[c]
            if q.size:
                forb = np.zeros(flat.size, dtype=bool)
                forb[self.conf_flat[c][self.c_mask[q, x[self.c_early[q]], :].ravel()]] = True
                forb = forb.reshape(-1, L)
                allowed = np.where(forb, np.inf, cost)
                stuck = np.asarray(~np.isfinite(allowed).any(axis=1))
                cost = np.where(stuck[:, None], cost, allowed)
            x[nodes] = np.argmin(cost, axis=1)
        return x


def minimize(mrf: PairwiseMRF, options: Options) -> MRFResult:
    """TRW-S; see the module docstring."""
    t_start = time.perf_counter()
    deadline = None if options.time_limit is None else t_start + options.time_limit
    penalty = auto_penalty(mrf) if options.conflict_penalty is None else options.conflict_penalty
    ch = _Chains(mrf, penalty)
    fw = np.zeros((ch.P, ch.L))
    bw = np.zeros((ch.P, ch.L))
    dfw = np.zeros(ch.P)
    dbw = np.zeros(ch.P)
    best = Incumbent(mrf)
    trace, bounds, decoded = [], [], []
    lb = -np.inf
    it = 0
    for it in range(1, options.max_iter + 1):  # noqa: B007 (the count of iterations run, read after the loop)
        ch.forward(fw, bw, dfw)
        ch.backward(fw, bw, dbw)
        prev = lb
        bounds.append(ch.bound(fw, bw, dbw, ch.n_in))
        lb = max(lb, bounds[-1])
        decoded.append(best.offer(ch.decode(fw, bw)))
        trace.append(best.energy)
        if best.energy - lb <= options.tol or lb - prev <= options.tol * max(1.0, abs(lb)):
            break
        if deadline is not None and time.perf_counter() >= deadline:
            break
    stats = {"penalty": penalty, "pairs": ch.P, "colours": len(ch.classes), "bounds": bounds,
             "decoded_energy": decoded}
    return best.result("trws", options, trace, it, t_start, deadline, stats,
                       lower_bound=float(lb) if np.isfinite(lb) else None)


BACKEND = Backend(
    name="trws",
    entry=minimize,
    summary="sequential tree-reweighted message passing with lower bound (Kolmogorov 2006)",
    capabilities=MRFCapabilities(optimal=False, lower_bound=True, exact_on_trees=True, monotone=False, stochastic=False),
)
