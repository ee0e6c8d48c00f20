"""Straightening a robot's path: the same steps, no longer moves, a shorter way (``mrf.straighten``).

Each MRF step picks every robot's next cell among its neighbours, and a robot that makes
room for another or funnels into a doorway often zigzags: two diagonal moves, up-right
then down-right, where two straight moves would reach the same cell. Flown on the common
time grid a step lasts as long as its longest move needs (a diagonal cell at v_max takes
1.41 times a straight one), and every zigzag turns the robot twice.

After the MRF has chosen the paths (after :mod:`~mrfswarm.discrete.loops`, before
:mod:`~mrfswarm.discrete.merge_waits`), :func:`straighten` replaces the cells of a robot
between two of its steps s and s + k (k <= :data:`WINDOW`) by the shortest way between
the same two cells in the same k steps, where

- each new move is no longer than the robot's move in that step (so no step's longest move
  grows, and a robot's moves stay within the MRF's move order), and a wait stays a wait and
  a move a move;
- every cell is free and every move keeps half a cell from occupied cells, the obstacle
  rules of :mod:`mrfswarm.discrete.safety`, from one table of the map's clear moves;
- the robot stays at least one cell (in the downwash-scaled metric) from every other robot
  during steps s..s + k (:func:`~mrfswarm.discrete.merge_waits.robot_clear`), and the whole
  plan is checked again afterwards.

The way is found by a dynamic program over the cells within reach of both ends (at most
(2k + 1)^d); only the windows whose length exceeds the shortest 8- (26-) connected length of
their displacement are searched, found for the whole plan at once. A robot's start, end and
step count are kept, so the plan's length is unchanged. Measured (flight_quality bench, one
run each): see the README's ``mrf.straighten`` row.

This is a post-process of the paper's method (its robots keep the MRF's cells);
``mrf.straighten = false`` turns it off, as the paper's scenario configs do.
"""

from __future__ import annotations

import itertools
import math
from functools import lru_cache

import numpy as np

from mrfswarm.discrete.merge_waits import robot_clear
from mrfswarm.discrete.motion import segments_clear
from mrfswarm.geometry import downwash_scale

#: Steps per window at most (its end cells kept). Flown (default, refined): 4, 6 and 8 flew the doorway 11.05, 10.70
#: and 10.50 s (refined 11.08, 10.82, 10.62), the arena 5.99, 5.88, 5.78 (5.70, 5.59, 5.48), the forest 24.68, 24.47,
#: 24.16 (22.54, 22.32, 21.82), the rooms 26.08, 25.64, 25.31 (24.21, 24.36, 24.21); 8 took clutter40 0.38 s, 4 0.06 s.
WINDOW = 8
#: Sweeps over all robots; a robot straightened can let a neighbour straighten.
PASSES = 3
_TOL = 1e-9


@lru_cache(maxsize=2)
def unit_moves(ndim: int) -> tuple[np.ndarray, np.ndarray]:
    """(M, d) the moves with every component in {-1, 0, 1}, the wait first, and (M,) their lengths (cells)."""
    moves = np.array(sorted(itertools.product((-1, 0, 1), repeat=ndim), key=lambda m: sum(map(abs, m))),
                     dtype=np.int64)
    moves.setflags(write=False)
    lengths = np.linalg.norm(moves, axis=1)
    lengths.setflags(write=False)
    return moves, lengths


def shortest_lengths(offsets: np.ndarray) -> np.ndarray:
    """(...,) the length of the shortest 8-connected (26 in 3-D) way of each offset (..., d), in cells."""
    a = -np.sort(-np.abs(np.asarray(offsets, dtype=float)), axis=-1)
    if a.shape[-1] == 2:
        return (a[..., 0] - a[..., 1]) + math.sqrt(2) * a[..., 1]
    return (a[..., 0] - a[..., 1]) + math.sqrt(2) * (a[..., 1] - a[..., 2]) + math.sqrt(3) * a[..., 2]


def clear_moves(free: np.ndarray) -> np.ndarray:
    """(*free.shape, M) whether each unit move (:func:`unit_moves`) from each cell ends in a free cell and keeps
    half a cell from occupied cells (:func:`~mrfswarm.discrete.motion.segments_clear`); False from occupied cells."""
    moves, _ = unit_moves(free.ndim)
    cells = np.argwhere(free)
    out = np.zeros((*free.shape, len(moves)), dtype=bool)
    for k, m in enumerate(moves):
        out[(*cells.T, k)] = segments_clear(free, cells, cells + m)
    return out


def shortest_way(column: np.ndarray, s: int, e: int, clear: np.ndarray) -> np.ndarray | None:
    """The robot's cells of steps s..e (e - s + 1, d) on the shortest way from ``column[s]`` to ``column[e]`` whose
    move in each step is no longer than the column's and is a wait exactly where the column waits; None if no such
    way is shorter than the column's own.

    A dynamic program over the box of cells within e - s moves of both ends; ``clear`` is :func:`clear_moves`.
    """
    own = np.linalg.norm(np.diff(column[s:e + 1], axis=0), axis=1)
    cost, way = _dynamic_program(column[s], column[e], own, clear)
    return way if cost < own.sum() - 1e-6 else None


def _unobstructed(offset: np.ndarray, caps: np.ndarray) -> float:
    """The length of the shortest way of ``offset`` in steps capped as ``caps`` (a move's length at most its step's,
    a wait exactly where the cap is 0) on a free map: no way among obstacles is shorter. On a free map the moves'
    order and the axes' signs and order do not matter, so the way is searched once per sorted |offset| and
    sorted caps."""
    return _unobstructed_sorted(tuple(sorted(np.abs(offset).tolist())), tuple(sorted(np.round(caps, 9).tolist())))


@lru_cache(maxsize=4096)
def _unobstructed_sorted(offset: tuple[int, ...], caps: tuple[float, ...]) -> float:
    k, d = len(caps), len(offset)
    clear = np.ones((2 * k + 1,) * d + (3**d,), dtype=bool)
    start = np.full(d, k)
    return _dynamic_program(start, start + np.asarray(offset), np.asarray(caps), clear)[0]


def _dynamic_program(a: np.ndarray, b: np.ndarray, own: np.ndarray,
                     clear: np.ndarray) -> tuple[float, np.ndarray | None]:
    """The shortest way's length and cells (k + 1, d) from cell ``a`` to cell ``b`` in k = len(own) steps, each
    move no longer than ``own``'s and a wait exactly where ``own`` is 0 (inf and None if there is none)."""
    moves, lengths = unit_moves(len(a))
    k = len(own)
    shape = np.asarray(clear.shape[:-1])
    lo = np.maximum(np.maximum(a, b) - k, 0)
    hi = np.minimum(np.minimum(a, b) + k, shape - 1)
    if np.any(hi < lo):
        return np.inf, None
    box = tuple(int(v) for v in hi - lo + 1)
    local = clear[tuple(slice(int(x), int(y) + 1) for x, y in zip(lo, hi))]
    cost = np.full(box, np.inf)
    cost[tuple(a - lo)] = 0.0
    came = []  # per step: (box) the move index taken into each cell
    for t in range(k):
        allowed = (lengths <= own[t] + _TOL) & ((lengths > 0) == (own[t] > 0))
        new = np.full(box, np.inf)
        how = np.full(box, -1, dtype=np.int64)
        for j in np.flatnonzero(allowed).tolist():
            m = moves[j]
            # sources x with x + m in the box
            src = tuple(slice(max(0, -int(v)), n - max(0, int(v))) for v, n in zip(m, box))
            dst = tuple(slice(max(0, int(v)), n - max(0, -int(v))) for v, n in zip(m, box))
            where: tuple = (*src, j)
            val = np.where(local[where], cost[src] + lengths[j], np.inf)
            better = val < new[dst] - _TOL
            new[dst] = np.where(better, val, new[dst])
            how[dst] = np.where(better, j, how[dst])
        cost = new
        came.append(how)
    end = tuple(b - lo)
    if not np.isfinite(cost[end]):
        return np.inf, None
    out = np.empty((k + 1, len(a)), dtype=np.int64)
    cell = np.array(end)
    for t in range(k, 0, -1):
        out[t] = cell + lo
        cell = cell - moves[came[t - 1][tuple(cell)]]
    out[0] = cell + lo
    return float(cost[end]), out


def straighten(paths: np.ndarray, free: np.ndarray, downwash: float = 1.0,
               window: int = WINDOW) -> tuple[np.ndarray, int]:
    """The (T + 1, N, d) ``paths`` with each robot's way shortened where safe (see the module docstring), and the
    windows shortened.
    """
    P = np.array(paths, dtype=np.int64)
    T, N = len(P) - 1, P.shape[1]
    if T < 2 or N == 0:
        return P, 0
    scale = downwash_scale(P.shape[-1], downwash)
    # a straightened move is never longer than the one it replaces, per axis at most 1
    largest_move = float(np.abs(np.diff(P, axis=0)).max())
    clear = clear_moves(np.asarray(free, dtype=bool))
    done = 0
    for _ in range(PASSES):
        before = done
        for i, starts in _candidates(P, window).items():
            last = -1  # steps up to here were changed in this sweep: their windows are searched again next sweep
            for s in starts:
                if s < last:
                    continue
                col = P[:, i]
                own = np.linalg.norm(np.diff(col[s:s + window + 1], axis=0), axis=1)
                for k in range(min(window, T - s), 1, -1):
                    e = s + k
                    if own[:k].sum() <= _unobstructed(col[e] - col[s], own[:k]) + 1e-6:
                        continue  # no shorter way even on a free map
                    way = shortest_way(col, s, e, clear)
                    if way is None:
                        continue
                    new = col.copy()
                    new[s:e + 1] = way
                    if robot_clear(P, i, s, e, scale, new, largest_move):
                        P[:, i] = new
                        done += 1
                        last = e
                        break
        if done == before:
            break
    return P, done


def _candidates(P: np.ndarray, window: int) -> dict[int, list[int]]:
    """Robot -> the steps s (ascending) where some window s..s + k (k = 2..window) of its path is longer than the
    shortest way of its displacement."""
    L = np.linalg.norm(np.diff(P, axis=0), axis=-1)  # (T, N)
    C = np.concatenate([np.zeros((1, L.shape[1])), np.cumsum(L, axis=0)])
    slack = np.zeros(L.shape, dtype=bool)  # (T, N): s of a window with slack
    for k in range(2, min(window, len(L)) + 1):
        over = (C[k:] - C[:-k]) > shortest_lengths(P[k:] - P[:-k]) + 1e-6
        slack[:len(over)] |= over
    s, i = np.nonzero(slack)
    out: dict[int, list[int]] = {}
    for robot, step in zip(i.tolist(), s.tolist()):
        out.setdefault(robot, []).append(step)
    return out
