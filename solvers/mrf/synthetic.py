"""Synthetic MRFs with known structure, for tests and benchmarks of the methods.

:func:`random_mrf` gives small unstructured problems (brute-force checkable);
:func:`swarm_mrf` gives problems shaped like the planner's: robots on a grid choosing
among their 9-neighbourhood cells, k-nearest-neighbour edges with Morse-like pairwise
costs, a goal-seeking unary, and conflicts (same cell, swapped cells) between nearby
robots.
"""

from __future__ import annotations

import numpy as np

from solvers.mrf.problem import PairwiseMRF


def random_mrf(rng: np.random.Generator, N: int, L: int, p_edge: float = 0.6, p_conf: float = 0.4,
               p_forbid: float = 0.4, edges: np.ndarray | None = None) -> PairwiseMRF:
    """Random normal unary/pairwise costs and random conflicts that keep a random ``initial`` feasible.

    Each node has 1..L labels (at least one node has L); ``edges`` defaults to each pair
    with probability ``p_edge`` (both orientations occur); each pair is a conflict with
    probability ``p_conf`` and forbids each label pair with probability ``p_forbid``,
    except the initial one.
    """
    n_labels = rng.integers(1, L + 1, size=N)
    n_labels[rng.integers(N)] = L
    unary = rng.normal(size=(N, L))
    unary[np.arange(L)[None, :] >= n_labels[:, None]] = np.inf
    pairs = np.array([(i, j) for i in range(N) for j in range(i + 1, N)], dtype=np.intp).reshape(-1, 2)
    if edges is None:
        edges = pairs[rng.random(len(pairs)) < p_edge]
    edges = np.asarray(edges, dtype=np.intp).reshape(-1, 2)
    flip = rng.random(len(edges)) < 0.5
    edges = np.where(flip[:, None], edges[:, ::-1], edges)
    pairwise = rng.normal(size=(len(edges), L, L))
    initial = rng.integers(0, n_labels)
    conflicts = pairs[rng.random(len(pairs)) < p_conf]
    mask = rng.random((len(conflicts), L, L)) < p_forbid
    if len(conflicts):
        mask[np.arange(len(conflicts)), initial[conflicts[:, 0]], initial[conflicts[:, 1]]] = False
    return PairwiseMRF(unary, edges, pairwise, conflicts, mask, initial)


_MOVES = np.array([[0, 0], [1, 0], [-1, 0], [0, 1], [0, -1], [1, 1], [1, -1], [-1, 1], [-1, -1]], dtype=float)


def swarm_mrf(N: int, L: int = 9, k: int = 7, seed: int = 0, density: float = 0.4,
              conflict_radius: float = 2.9) -> PairwiseMRF:
    """A planner-like MRF: N robots on distinct grid cells, each choosing a cell of its 3x3 block.

    Label 0 is "stay" (``initial`` = all zeros, feasible); labels 1..L-1 are neighbour
    cells, some nodes having fewer (inf padding). Unary = distance of the target cell to
    a goal beyond the swarm; edges = symmetric k nearest neighbours, pairwise = a Morse
    potential of the two target cells' distance times a clique count in 1..3; conflicts
    between robots within ``conflict_radius`` cells forbid the same target cell and
    swapping cells.
    """
    if not 1 <= L <= len(_MOVES):
        raise ValueError(f"L must be in 1..{len(_MOVES)}, got {L}")
    rng = np.random.default_rng(seed)
    side = int(np.ceil(np.sqrt(N / density)))
    cells = rng.choice(side * side, size=N, replace=False)
    pos = np.stack([cells // side, cells % side], 1).astype(float)
    tgt = pos[:, None, :] + _MOVES[None, :L]
    goal = np.array([side * 1.5, side * 0.5])
    unary = 0.05 * np.linalg.norm(tgt - goal, axis=2)
    n_labels = rng.integers(max(1, L - 3), L + 1, size=N)
    unary[np.arange(L)[None, :] >= n_labels[:, None]] = np.inf
    # neighbours by sorting squared distances per robot (O(N^2), fine up to a few thousand)
    d2 = ((pos[:, None, :] - pos[None, :, :]) ** 2).sum(axis=2)
    np.fill_diagonal(d2, np.inf)
    kk = min(k, N - 1)
    nn = np.argsort(d2, axis=1)[:, :kk]
    e = np.sort(np.stack([np.repeat(np.arange(N), kk), nn.ravel()], 1), axis=1)
    edges = np.unique(e, axis=0) if len(e) else np.zeros((0, 2), dtype=np.intp)
    dist = np.linalg.norm(tgt[edges[:, 0]][:, :, None, :] - tgt[edges[:, 1]][:, None, :, :], axis=3)
    morse = -0.7 * np.exp(-dist / 14.0) + 0.9 * np.exp(-dist / 4.0) + 0.3
    pairwise = morse * rng.integers(1, 4, size=(len(edges), 1, 1))
    i, j = np.nonzero(np.triu(d2 <= conflict_radius ** 2))
    conflicts = np.stack([i, j], 1)
    ti, tj = tgt[i], tgt[j]
    same = np.all(np.abs(ti[:, :, None, :] - tj[:, None, :, :]) < 0.5, axis=3)
    swap = (np.all(np.abs(ti - pos[j][:, None, :]) < 0.5, axis=2)[:, :, None]
            & np.all(np.abs(tj - pos[i][:, None, :]) < 0.5, axis=2)[:, None, :])
    return PairwiseMRF(unary, edges, pairwise, conflicts, same | swap, np.zeros(N, dtype=np.intp))
