"""The lazy flipper: exhaustive search over joint changes of small connected sets of nodes.

Andres, B., Kappes, J. H., Beier, T., Köthe, U. & Hamprecht, F. A. (2012). "The Lazy
Flipper: Efficient Depth-Limited Exhaustive Search in Discrete Graphical Models". ECCV.

Adapted to many labels and hard conflicts. Starts from ICM's result (so it never ends
above ICM). A *move* relabels a connected set S of 2..``Options.max_flip`` nodes of the
union graph (edges + conflicts; conflict-coupled robots are exactly the ones that may
only move together, e.g. one robot stepping into the cell another leaves) to the jointly
best labels given all other nodes, among the joint labellings that break no conflict:

.. math::

    \\min_{x_S} \\sum_{i \\in S} \\ell_i^{-S}(x_i \\mid x) + \\sum_{(i,j) \\subset S} W_{ij}(x_i, x_j),

with \\ell_i^{-S} the local energy of i without its pairs inside S; that is all L^|S|
joint labellings, evaluated as one broadcast array per batch of sets. A move is made
if it lowers E by more than ``Options.tol``. Size-one moves are ICM, which runs again
after every round of moves.

Laziness, as in the paper: a set once found not to improve is not evaluated again until
a node in it or next to it changes label. Each round evaluates the pending sets of the
smallest size that has any, makes a greedy (best decrease first) selection of improving
moves that touch no common node and no pair of nodes, applies them at once (their
energy changes add up) and restarts from size 2; it stops when no set of any size
improves, after ``Options.max_iter`` rounds, or at ``Options.time_limit``. The energy
never increases and every labelling stays feasible.

The number of connected sets grows like N d^(k-1) for degree d, and each costs L^k, so
``max_flip`` 2 (default) or 3 are practical for swarm-size problems.
"""

from __future__ import annotations

import time

import numpy as np

from solvers.mrf.capabilities import MRFCapabilities
from solvers.mrf.icm import descend
from solvers.mrf.local_energy import LocalEnergy, colour_sweep, neighbours, union_adjacency
from solvers.mrf.problem import PairwiseMRF
from solvers.mrf.result import MRFResult, Options
from solvers.registry import Backend

_CHUNK_ELEMENTS = 1 << 21


def connected_subsets(indptr: np.ndarray, nbr: np.ndarray, kmax: int) -> list[np.ndarray]:
    """All connected node sets of sizes 1..kmax, as sorted rows: element k-1 is (M_k, k)."""
    N = indptr.size - 1
    deg = np.diff(indptr)
    subs = [np.arange(N, dtype=np.intp)[:, None]]
    for k in range(2, kmax + 1):
        prev = subs[-1]
        parts = []
        for m in range(k - 1):
            rows = np.repeat(np.arange(len(prev)), deg[prev[:, m]])
            parts.append(np.column_stack([prev[rows], neighbours(indptr, nbr, prev[:, m])]))
        cand = np.concatenate(parts) if parts else np.zeros((0, k), np.intp)
        cand = cand[(cand[:, :-1] != cand[:, -1:]).all(axis=1)]
        cand = np.unique(np.sort(cand, axis=1), axis=0) if len(cand) else np.zeros((0, k), np.intp)
        subs.append(cand)
    return subs


class _PairLookup:
    """Index of the pair {u, v} in ``pairs`` (or -1) and whether it is stored as (v, u)."""

    def __init__(self, pairs: np.ndarray, n: int) -> None:
        self.pairs, self.n = pairs, n
        key = np.minimum(pairs[:, 0], pairs[:, 1]).astype(np.int64) * n + np.maximum(pairs[:, 0], pairs[:, 1])
        self.order = np.argsort(key)
        self.key = key[self.order]

    def __call__(self, u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if not self.key.size:
            return np.full(u.size, -1, dtype=np.intp), np.zeros(u.size, dtype=bool)
        k = np.minimum(u, v).astype(np.int64) * self.n + np.maximum(u, v)
        at = np.minimum(np.searchsorted(self.key, k), self.key.size - 1)
        idx = np.where(self.key[at] == k, self.order[at], -1)
        rev = (idx >= 0) & (self.pairs[np.maximum(idx, 0), 0] != u)
        return idx, rev


def _axes(t: np.ndarray, at: tuple[int, ...], k: int) -> np.ndarray:
    """Reshape (M, L[, L]) so its label axes sit at positions ``at`` of an (M,) + (L,)*k array."""
    shape = [t.shape[0]] + [1] * k
    for ax, n in zip(at, t.shape[1:]):
        shape[ax + 1] = n
    return t.reshape(shape)


class _Flipper:
    def __init__(self, mrf: PairwiseMRF) -> None:
        self.mrf = mrf
        self.everyone = LocalEnergy(mrf, np.arange(mrf.n_nodes))
        self.edges = _PairLookup(mrf.edges, mrf.n_nodes)
        self.confs = _PairLookup(mrf.conflicts, mrf.n_nodes)

    def best_moves(self, sets: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """For each row of ``sets``: the decrease of E by its best joint relabelling, and those labels."""
        mrf = self.mrf
        L = mrf.max_labels
        M, k = sets.shape
        local = self.everyone.costs(x)
        count = self.everyone.conflict_counts(x)
        gain = np.empty(M)
        labels = np.empty((M, k), dtype=np.intp)
        step = max(1, _CHUNK_ELEMENTS // L ** k)
        for s in range(0, M, step):
            S = sets[s:s + step]
            m = len(S)
            own = [local[S[:, a]].copy() for a in range(k)]
            cnt = [count[S[:, a]].copy() for a in range(k)]
            total = np.zeros((m,) + (L,) * k)
            for a in range(k):
                for b in range(a + 1, k):
                    u, v = S[:, a], S[:, b]
                    e, rev = self.edges(u, v)
                    has = e >= 0
                    if has.any():
                        W = mrf.pairwise[np.maximum(e, 0)]
                        W = np.where(rev[:, None, None], W.transpose(0, 2, 1), W)
                        W = np.where(has[:, None, None], W, 0.0)
                        own[a] -= W[np.arange(m), :, x[v]]
                        own[b] -= W[np.arange(m), x[u], :]
                        total += _axes(W, (a, b), k)
                    c, crev = self.confs(u, v)
                    has = c >= 0
                    if has.any():
                        C = mrf.conflict_mask[np.maximum(c, 0)]
                        C = np.where(crev[:, None, None], C.transpose(0, 2, 1), C) & has[:, None, None]
                        cnt[a] -= C[np.arange(m), :, x[v]]
                        cnt[b] -= C[np.arange(m), x[u], :]
                        total += _axes(np.where(C, np.inf, 0.0), (a, b), k)
            for a in range(k):
                total += _axes(np.where(cnt[a] > 0.5, np.inf, own[a]), (a,), k)
            flat = total.reshape(m, -1)
            cur_idx = np.ravel_multi_index(tuple(x[S].T), (L,) * k)
            best = np.argmin(flat, axis=1)
            gain[s:s + m] = flat[np.arange(m), cur_idx] - flat[np.arange(m), best]
            labels[s:s + m] = np.column_stack(np.unravel_index(best, (L,) * k))
        return gain, labels


def _select(sets: np.ndarray, gain: np.ndarray, indptr: np.ndarray, nbr: np.ndarray, n: int) -> np.ndarray:
    """Greedy, largest gain first: moves whose sets share no node and no pair."""
    blocked = np.zeros(n, dtype=bool)
    chosen = []
    for j in np.argsort(-gain, kind="stable"):
        s = sets[j]
        if blocked[s].any():
            continue
        chosen.append(j)
        blocked[s] = True
        for u in s:
            blocked[nbr[indptr[u]:indptr[u + 1]]] = True
    return np.array(chosen, dtype=np.intp)


def minimize(mrf: PairwiseMRF, options: Options) -> MRFResult:
    """ICM, then lazy-flipper moves of up to ``options.max_flip`` nodes; see the module docstring."""
    t0 = time.perf_counter()
    deadline = None if options.time_limit is None else t0 + options.time_limit
    N = mrf.n_nodes
    sweep = colour_sweep(mrf)
    indptr, nbr = union_adjacency(mrf)
    x, trace, icm_moves = descend(mrf, mrf.initial, sweep, options.max_iter, options.tol, deadline, (indptr, nbr))
    icm_energy = trace[-1]
    sets = connected_subsets(indptr, nbr, options.max_flip)[1:]
    clean = [np.zeros(len(s), dtype=bool) for s in sets]
    flipper = _Flipper(mrf)
    made = {k: 0 for k in range(2, options.max_flip + 1)}
    evaluated = 0
    rounds = 0
    while rounds < options.max_iter and sets:
        if deadline is not None and time.perf_counter() >= deadline:
            break
        rounds += 1
        moved = False
        for ki, S in enumerate(sets):
            todo = np.flatnonzero(~clean[ki])
            if not todo.size:
                continue
            gain, labels = flipper.best_moves(S[todo], x)
            evaluated += todo.size
            good = gain > options.tol
            clean[ki][todo[~good]] = True
            if not good.any():
                continue
            cand = todo[good]
            pick = _select(S[cand], gain[good], indptr, nbr, N)
            old = x.copy()
            flipped = S[cand[pick]].ravel()
            x[flipped] = labels[good][pick].ravel()
            made[ki + 2] += pick.size
            # if x was an ICM fixed point, only the flipped nodes' neighbours may now move alone
            near = None
            if icm_moves[-1] == 0:
                near = np.zeros(N, dtype=bool)
                near[neighbours(indptr, nbr, flipped)] = True
            x, icm_trace, more = descend(mrf, x, sweep, options.max_iter, options.tol, deadline, (indptr, nbr), near)
            icm_moves += more
            changed = np.flatnonzero(x != old)
            touched = np.zeros(N, dtype=bool)
            touched[changed] = True
            touched[neighbours(indptr, nbr, changed)] = True
            for kj, T in enumerate(sets):
                clean[kj] &= ~touched[T].any(axis=1)
            trace.append(icm_trace[-1])
            moved = True
            break
        if not moved:
            break
    return MRFResult(
        labels=x,
        energy=trace[-1],
        energy_trace=np.array(trace),
        iterations=rounds,
        time_s=time.perf_counter() - t0,
        method="lazy_flipper",
        stats={"icm_energy": icm_energy, "moves": {f"size_{k}": n for k, n in made.items()},
               "icm_moves": int(sum(icm_moves)), "sets": [len(s) for s in sets], "evaluated": evaluated},
    )


BACKEND = Backend(
    name="lazy_flipper",
    entry=minimize,
    summary="lazy flipper (Andres et al. 2012): ICM, then joint moves of connected node sets",
    capabilities=MRFCapabilities(optimal=False, lower_bound=False, exact_on_trees=False, monotone=True, stochastic=False),
)
