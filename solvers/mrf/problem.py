"""The discrete energy every MRF method minimizes.

A pairwise MRF over N nodes, node i choosing a label x_i in {0, ..., L_i - 1}:

.. math::

    E(x) = \\sum_i U_i(x_i) + \\sum_{e=(i,j)} W_e(x_i, x_j)

subject to hard conflicts: for each conflict pair c = (i, j), ``conflict_mask[c, x_i, x_j]``
must be False. Labels are padded to a common L = max L_i; the padding of node i is
marked by ``unary[i, l] = inf`` for l >= L_i, and valid labels are the prefix
0..L_i-1. Pairwise costs are finite (hard constraints are conflicts, never costs), and
already include their weights. ``initial`` is a feasible labelling that every method may
start from and that :func:`repair` falls back to.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from solvers.errors import InvalidProblem, real_array


@dataclass(frozen=True, eq=False)
class PairwiseMRF:
    """A validated pairwise MRF with hard pairwise conflicts.

    Parameters
    ----------
    unary
        (N, L) costs; ``inf`` exactly on the padding beyond each node's labels.
    edges
        (E, 2) node pairs (i != j, each unordered pair at most once).
    pairwise
        (E, L, L) finite costs, ``pairwise[e, a, b]`` for ``x[edges[e,0]] = a`` and
        ``x[edges[e,1]] = b``.
    conflicts
        (C, 2) node pairs that carry hard constraints (may differ from ``edges``).
    conflict_mask
        (C, L, L) booleans, True where the label pair is forbidden.
    initial
        (N,) a feasible labelling.
    priority
        Optional (N,) finite numbers: the order in which sequential methods visit the nodes
        (those of higher priority first, where they interact). It does not change the
        energy; where a method's result depends on the order (ICM takes a cell two nodes
        could move to for the one it visits first), it decides. None: the methods' own order.
    """

    unary: np.ndarray
    edges: np.ndarray
    pairwise: np.ndarray
    conflicts: np.ndarray
    conflict_mask: np.ndarray
    initial: np.ndarray
    priority: np.ndarray | None = None

    def __post_init__(self) -> None:
        unary = np.ascontiguousarray(real_array(self.unary, "unary"))
        if unary.ndim != 2 or unary.shape[0] < 1 or unary.shape[1] < 1:
            raise InvalidProblem(f"unary must be (N, L) with N, L >= 1, got shape {unary.shape}")
        N, L = unary.shape
        # shapes checked, not reshaped: (3, 2) edges given as (2, 3) were read as other edges
        edges = _rows("edges", self.edges, (2,), np.intp)
        pairwise = _rows("pairwise", self.pairwise, (L, L), float) if len(edges) else np.zeros((0, L, L))
        conflicts = _rows("conflicts", self.conflicts, (2,), np.intp)
        cmask = _rows("conflict_mask", self.conflict_mask, (L, L), bool) if len(conflicts) else np.zeros((0, L, L), bool)
        initial = _rows("initial", self.initial, (), np.intp)
        if np.isnan(unary).any() or np.isneginf(unary).any():
            raise InvalidProblem("unary costs must not be NaN or -inf")
        finite = np.isfinite(unary)
        n_labels = finite.sum(axis=1)
        if np.any(n_labels < 1):
            raise InvalidProblem(f"node {int(np.argmin(n_labels))} has no label")
        if np.any(finite != (np.arange(L)[None, :] < n_labels[:, None])):
            raise InvalidProblem("each node's valid labels must be the prefix 0..L_i-1 (inf only as padding)")
        if pairwise.shape[0] != edges.shape[0]:
            raise InvalidProblem(f"pairwise has {pairwise.shape[0]} tables for {edges.shape[0]} edges")
        if not np.all(np.isfinite(pairwise)):
            raise InvalidProblem("pairwise costs must be finite; express hard constraints as conflicts")
        if cmask.shape[0] != conflicts.shape[0]:
            raise InvalidProblem(f"conflict_mask has {cmask.shape[0]} tables for {conflicts.shape[0]} conflict pairs")
        for name, pairs in (("edges", edges), ("conflicts", conflicts)):
            if pairs.size and (pairs.min() < 0 or pairs.max() >= N):
                raise InvalidProblem(f"{name} refer to nodes outside 0..{N - 1}")
            if np.any(pairs[:, 0] == pairs[:, 1]):
                raise InvalidProblem(f"{name} contain a self-loop")
            key = np.sort(np.minimum(pairs[:, 0], pairs[:, 1]) * np.int64(N) + np.maximum(pairs[:, 0], pairs[:, 1]))
            if np.any(key[1:] == key[:-1]):
                raise InvalidProblem(f"{name} contain a repeated pair")
        if initial.shape != (N,):
            raise InvalidProblem(f"initial has shape {initial.shape}, expected ({N},)")
        if self.priority is not None:
            priority = np.asarray(self.priority, dtype=float)
            if priority.shape != (N,) or not np.all(np.isfinite(priority)):
                raise InvalidProblem(f"priority must be (N,) = ({N},) finite numbers, got shape {priority.shape}"
                                     + ("" if priority.shape != (N,) else " with non-finite entries"))
            object.__setattr__(self, "priority", priority)
        for name, val in (("unary", unary), ("edges", edges), ("pairwise", pairwise),
                          ("conflicts", conflicts), ("conflict_mask", cmask), ("initial", initial)):
            object.__setattr__(self, name, val)
        if not self.is_feasible(initial):
            raise InvalidProblem("the initial labelling violates a label range or a hard conflict")

    @property
    def n_nodes(self) -> int:
        return self.unary.shape[0]

    @property
    def max_labels(self) -> int:
        return self.unary.shape[1]

    @cached_property
    def n_labels(self) -> np.ndarray:
        """(N,) number of valid labels of each node."""
        return np.isfinite(self.unary).sum(axis=1)

    def energy(self, labels: np.ndarray) -> float:
        """E(labels), ignoring conflicts (see :meth:`is_feasible`)."""
        x = np.asarray(labels, dtype=np.intp)
        e = self.unary[np.arange(self.n_nodes), x].sum()
        if len(self.edges):
            e += self.pairwise[np.arange(len(self.edges)), x[self.edges[:, 0]], x[self.edges[:, 1]]].sum()
        return float(e)

    def violated_conflicts(self, labels: np.ndarray) -> np.ndarray:
        """Indices of the conflict pairs that ``labels`` violates."""
        x = np.asarray(labels, dtype=np.intp)
        if not len(self.conflicts):
            return np.zeros(0, dtype=np.intp)
        bad = self.conflict_mask[np.arange(len(self.conflicts)), x[self.conflicts[:, 0]], x[self.conflicts[:, 1]]]
        return np.flatnonzero(bad)

    def is_feasible(self, labels: np.ndarray) -> bool:
        """True if every label is valid and no conflict is violated."""
        x = np.asarray(labels)
        if x.shape != (self.n_nodes,) or np.any(x < 0) or np.any(x >= self.n_labels):
            return False
        return self.violated_conflicts(x).size == 0


def repair(mrf: PairwiseMRF, labels: np.ndarray) -> tuple[np.ndarray, int]:
    """Make ``labels`` feasible by sending offending nodes back to ``mrf.initial``.

    Nodes with an invalid label, and both nodes of every violated conflict, return to
    their initial label; this repeats until no conflict is violated, which it must,
    because the all-initial labelling is feasible.

    Returns
    -------
    labels
        A feasible labelling.
    n_repaired
        How many nodes were sent back.
    """
    x = np.array(labels, dtype=np.intp, copy=True)
    reverted = np.zeros(mrf.n_nodes, dtype=bool)
    bad = (x < 0) | (x >= mrf.n_labels)
    while True:
        x[bad] = mrf.initial[bad]
        reverted |= bad
        viol = mrf.violated_conflicts(x)
        if viol.size == 0:
            return x, int(np.count_nonzero(reverted & (x != np.asarray(labels))))
        bad = np.zeros(mrf.n_nodes, dtype=bool)
        bad[mrf.conflicts[viol].ravel()] = True


def _rows(name: str, value: object, tail: tuple[int, ...], dtype: type) -> np.ndarray:
    """``value`` as an (m, *tail) array of ``dtype`` (empty: m = 0), or InvalidProblem naming its shape; integer
    arrays must hold whole numbers (0.7 as a label was read as 0), not booleans."""
    a = np.asarray(value) if isinstance(value, np.ndarray) and value.dtype.kind in "biu" else real_array(value, name)
    if a.size == 0:
        return np.zeros((0, *tail), dtype=dtype)
    if a.ndim != 1 + len(tail) or a.shape[1:] != tail:
        want = ", ".join(["m", *map(str, tail)])
        raise InvalidProblem(f"{name} must have shape ({want}), got {a.shape}")
    # [[False, True]] as edges was read as the edge (0, 1) (a library tour); real_array made a list's bools floats
    if dtype is np.intp and np.asarray(value).dtype.kind == "b":
        shown = " ".join(repr(value).split())
        raise InvalidProblem(f"{name} = {shown:.60}: must hold integer indices, not booleans")
    if dtype is np.intp and a.dtype.kind == "f" and (not np.all(np.isfinite(a)) or np.any(a != np.round(a))):
        raise InvalidProblem(f"{name} must hold whole numbers")
    return np.ascontiguousarray(a, dtype=dtype)
