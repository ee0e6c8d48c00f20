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
(2k + 1)^d), one per window start for the windows of every length from there; only the
windows longer than the shortest way of their displacement in the same capped steps on a
free map are searched, found for the whole plan at once (the free-map length once per
distinct sorted displacement and caps). The flight-quality bench's 200 robots in 15 % clutter
(straightened twice, see :mod:`~mrfswarm.discrete.planner`) took 16.3 s before that table and
the shared program, 5.1 s after, clutter40 0.63 s -> 0.37 s, to the same plans (one run each).
A robot's start, end and step count are kept, so the plan's length is unchanged. Measured
(flight_quality bench, one run each): see the README's ``mrf.straighten`` row.

This is a post-process of the paper's method (its robots keep the MRF's cells);
``mrf.straighten = false`` turns it off, as the paper's scenario configs do.
"""

from __future__ import annotations

import itertools
import math
from functools import lru_cache
from typing import Any

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


def clear_into(clear: np.ndarray) -> np.ndarray:
    """(M, *shape) whether each unit move (:func:`unit_moves`) into each cell is clear, from :func:`clear_moves`'
    table (*shape, M) of the moves out of each cell; False where the move would come from off the map."""
    moves, _ = unit_moves(clear.ndim - 1)
    shape = clear.shape[:-1]
    out = np.zeros((len(moves), *shape), dtype=bool)
    for k, m in enumerate(moves.tolist()):
        to = tuple(slice(max(0, v), n + min(0, v)) for v, n in zip(m, shape))
        out[k][to] = clear[..., k][tuple(slice(max(0, -v), n - max(0, v)) for v, n in zip(m, shape))]
    return out


#: The last map's :func:`clear_into` table, kept for the next plan on the same map: ``contested = "auto"`` plans up to
#: three times, and the table is of the whole map (a 2000 x 2000 map: 8.4 s each time, for 5 robots; a map tour).
_LAST_INTO: list[tuple[np.ndarray, np.ndarray]] = []


def _clear_into_of(free: np.ndarray) -> np.ndarray:
    """:func:`clear_into` of :func:`clear_moves` of ``free``, computed once per map in a row."""
    if _LAST_INTO and np.array_equal(_LAST_INTO[0][0], free):
        return _LAST_INTO[0][1]
    into = clear_into(clear_moves(free))
    into.flags.writeable = False  # shared by the plans that follow
    _LAST_INTO[:] = [(free.copy(), into)]
    return into


@lru_cache(maxsize=4096)
def _unobstructed_sorted(offset: tuple[int, ...], caps: tuple[float, ...]) -> float:
    """The length of the shortest way of ``offset`` in steps capped as ``caps`` (a move's length at most its step's,
    a wait exactly where the cap is 0) on a free map: no way among obstacles is shorter. On a free map the moves'
    order and the axes' signs and order do not matter, so the way is searched once per sorted |offset| and
    sorted caps."""
    k, d = len(caps), len(offset)
    into = np.ones((3**d,) + (2 * k + 1,) * d, dtype=bool)
    end = np.full(d, k) + np.asarray(offset)
    return _Search(np.full(d, k), np.asarray(caps), into, [(k, end)]).cost(k, end)


class _Search:
    """The shortest ways from cell ``a`` in the steps capped as ``own`` (each move no longer than ``own``'s, a wait
    exactly where ``own`` is 0) to the cells ``ends`` (k, b): the way to b in the first k steps. One dynamic
    program over the cells within len(own) moves of ``a`` and within k moves of some end's b (a way to b in k
    steps stays within k moves of both a and b, so the box holds every cell of every way read, and its ties
    break as they would in a box of one end alone); ``into`` is :func:`clear_into`. The windows of every
    length that start at ``a`` read their ways off the same program.

    Each step t takes, into each cell, the first unit move (in :func:`unit_moves`' order) of those whose
    way is shortest (:func:`_cheapest`), all moves at once, and only into the cells within t moves of
    ``a`` and within k - t of some end's b after k >= t steps: the sources of those cells are within t - 1
    and k - t + 1, so each cell of a way read gets the value and move it gets in the whole box. With a
    loop over the moves into the whole box at every step, the search took 65 % of straightening 300
    robots in 3-D (26 moves and the wait) and 35 % of 1000 in the plane; the searches of those took
    4.9 and 0.92 s that way, 1.8 and 0.87 s this way.
    """

    def __init__(self, a: np.ndarray, own: np.ndarray, into: np.ndarray,
                 ends: list[tuple[int, np.ndarray]]) -> None:
        moves, lengths = unit_moves(len(a))
        K = len(own)
        shape = np.asarray(into.shape[1:])
        self.lo = np.maximum(a - K, 0)
        hi = np.minimum(a + K, shape - 1)
        # only the ways to ``ends`` (k, cell) are read: their cells are within k of the cell too
        self.lo = np.maximum(self.lo, np.min([b - k for k, b in ends], axis=0))
        hi = np.minimum(hi, np.max([b + k for k, b in ends], axis=0))
        box = tuple(int(v) for v in hi - self.lo + 1)
        # each step's costs in the box padded by a cell of no way on each side: a move's source of a cell is then
        # one place of the padded box's flat array, the same offset from every cell
        padded = tuple(n + 2 for n in box)
        places = np.arange(math.prod(padded)).reshape(padded)
        offset = moves @ np.array([math.prod(padded[k + 1:]) for k in range(len(box))])
        into = into[(slice(None), *(slice(int(x), int(y) + 1) for x, y in zip(self.lo, hi)))]  # (M, *box)
        costs = np.full((K + 1, *padded), np.inf)
        came = np.full((K, *box), -1, dtype=np.int64)  # per step: the move index taken into each cell
        start = [int(v) for v in a - self.lo]
        costs[0][tuple(v + 1 for v in start)] = 0.0
        flat = costs.reshape(K + 1, -1)
        tails = [(k, [int(v) for v in b - self.lo]) for k, b in ends]
        for t in range(1, K + 1):
            allowed = np.flatnonzero((lengths <= own[t - 1] + _TOL) & ((lengths > 0) == (own[t - 1] > 0)))
            # after t steps only the cells within t moves of a have a way, and of those only the ones within k - t
            # moves of an end's b after k steps are on a way read (their sources are within k - t + 1 of it)
            read = [(k - t, b) for k, b in tails if k >= t]
            if not read:
                break
            lows = [max(0, v - t, min(b[n] - r for r, b in read)) for n, v in enumerate(start)]
            near = tuple(slice(x, max(x, min(box[n], v + t + 1, max(b[n] + r for r, b in read) + 1)))
                         for n, (x, v) in enumerate(zip(lows, start)))
            inside = tuple(slice(x.start + 1, x.stop + 1) for x in near)
            source = places[inside].reshape(1, -1) - offset[allowed, None]  # (moves, cells)
            moving: tuple[Any, ...] = (allowed, *near)
            best, row = _cheapest(np.where(into[moving].reshape(source.shape),
                                           flat[t - 1][source] + lengths[allowed, None], np.inf))
            region = costs[t][inside].shape
            costs[t][inside] = best.reshape(region)
            came[t - 1][near] = np.where(row < 0, -1, allowed[row]).reshape(region)
        inner = tuple(slice(1, n + 1) for n in box)
        self.costs = [c[inner] for c in costs]
        self.came = list(came)

    def _local(self, b: np.ndarray) -> tuple[int, ...] | None:
        rel = np.asarray(b) - self.lo
        if np.any(rel < 0) or np.any(rel >= self.costs[0].shape):
            return None
        return tuple(int(v) for v in rel)

    def cost(self, k: int, b: np.ndarray) -> float:
        """The shortest way's length from ``a`` to cell ``b`` in the first k steps (inf if there is none)."""
        at = self._local(b)
        return np.inf if at is None else float(self.costs[k][at])

    def way(self, k: int, b: np.ndarray) -> np.ndarray:
        """Its cells (k + 1, d); ``cost(k, b)`` must be finite."""
        moves, _ = unit_moves(len(self.lo))
        out = np.empty((k + 1, len(self.lo)), dtype=np.int64)
        cell = np.array(self._local(b))
        for t in range(k, 0, -1):
            out[t] = cell + self.lo
            cell = cell - moves[self.came[t - 1][tuple(cell)]]
        out[0] = cell + self.lo
        return out


def _cheapest(ways: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(B,) each column's value and (B,) row of ``ways`` (M, B) as the rule "a row replaces the best so far where it
    is shorter by more than _TOL, the rows in order" leaves them (inf and -1 where all are inf).

    That rule picks the first row within _TOL / 2 of the column's least value where no value lies
    between _TOL / 2 and 2 _TOL above it: from there no row is shorter by _TOL, and each row before
    it is longer by more. The ways' lengths are sums of a window's unit moves, 1, sqrt(2) or
    sqrt(3) cells: two of them are the same up to rounding or, up to 16 moves, 7e-4 apart at
    least. Where a column has a value in that band all the same, the rows are taken in order.
    """
    if not len(ways):
        return np.full(ways.shape[1], np.inf), np.full(ways.shape[1], -1, dtype=np.int64)
    least = ways.min(axis=0)
    first = ways <= least + _TOL / 2
    if np.count_nonzero(ways <= least + 2 * _TOL) != np.count_nonzero(first):
        best, row = np.full(ways.shape[1], np.inf), np.full(ways.shape[1], -1, dtype=np.int64)
        for j, way in enumerate(ways):
            better = way < best - _TOL
            best, row = np.where(better, way, best), np.where(better, j, row)
        return best, row
    row = first.argmax(axis=0)
    return ways[row, np.arange(ways.shape[1])], np.where(least < np.inf, row, -1)


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
    into = _clear_into_of(np.asarray(free, dtype=bool))
    done = 0
    for _ in range(PASSES):
        before = done
        slack, order = _slack(P, window)
        for i, starts in _starts(slack, order).items():
            last = -1  # steps up to here were changed in this sweep: their windows are searched again next sweep
            for s in starts:
                if s < last:
                    continue
                col = P[:, i]
                ks = np.flatnonzero(slack[s, i])[::-1]  # the window lengths with room, longest first
                own = np.linalg.norm(np.diff(col[s:s + ks[0] + 1], axis=0), axis=1)
                search = _Search(col[s], own, into, [(k, col[s + k]) for k in ks.tolist()])
                for k in ks.tolist():
                    e = s + k
                    if search.cost(k, col[e]) >= own[:k].sum() - 1e-6:
                        continue
                    new = col.copy()
                    new[s:e + 1] = search.way(k, col[e])
                    if robot_clear(P, i, s, e, scale, new, largest_move):
                        P[:, i] = new
                        done += 1
                        last = e
                        break
        if done == before:
            break
    return P, done


def _slack(P: np.ndarray, window: int) -> tuple[np.ndarray, np.ndarray]:
    """(T, N, window + 1): whether robot i's window s..s + k (k = 2..window) is longer than the shortest way of its
    displacement in the same capped steps on a free map (:func:`_unobstructed_sorted`, searched once per distinct
    sorted offset and caps); only those windows can be shortened. And (T, N) whether some window from step s
    is longer than the shortest way with no caps (which the robots are visited in the order of)."""
    T, N = P.shape[0] - 1, P.shape[1]
    L = np.linalg.norm(np.diff(P, axis=0), axis=-1)  # (T, N)
    caps, kind = np.unique(np.round(L, 9), return_inverse=True)
    kind = kind.reshape(L.shape)
    counts = np.zeros((T + 1, N, len(caps)), dtype=np.int64)  # moves of each cap up to each step
    counts[1:] = np.cumsum(kind[..., None] == np.arange(len(caps)), axis=0)
    C = np.concatenate([np.zeros((1, N)), np.cumsum(L, axis=0)])
    # the ways searched are of unit moves (:func:`unit_moves`): a window with a longer move (mrf.order >= 4: two
    # cells along an axis) is kept as it is (its far end can lie beyond the search box: that crashed)
    long = np.concatenate([np.zeros((1, N), dtype=np.int64),
                           np.cumsum(np.abs(np.diff(P, axis=0)).max(axis=-1) > 1, axis=0)])
    out = np.zeros((T, N, window + 1), dtype=bool)
    uncapped = np.zeros((T, N), dtype=bool)
    for k in range(2, min(window, T) + 1):
        own = C[k:] - C[:-k]  # (T - k + 1, N)
        offset = np.sort(np.abs(P[k:] - P[:-k]), axis=-1)
        maybe = own > shortest_lengths(offset) + 1e-6  # longer than the free-map way without caps: may have room
        maybe &= long[k:] == long[:-k]
        if not maybe.any():
            continue
        uncapped[:T - k + 1] |= maybe
        keys = np.concatenate([offset[maybe], (counts[k:] - counts[:-k])[maybe]], axis=1)
        unique, back = _unique_rows(keys)
        d = offset.shape[-1]
        free = np.array([_unobstructed_sorted(tuple(row[:d].tolist()), tuple(np.repeat(caps, row[d:]).tolist()))
                         for row in unique])
        out[:T - k + 1, :, k][maybe] = own[maybe] > free[back.ravel()] + 1e-6
    return out, uncapped


def _unique_rows(keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``np.unique(keys, axis=0, return_inverse=True)`` of non-negative integer rows, sorted as one number each
    (a tenth of the time where the rows fit in 62 bits)."""
    base = int(keys.max(initial=0)) + 1
    if keys.shape[1] * math.log2(base) > 62:
        return np.unique(keys, axis=0, return_inverse=True)
    code = keys @ (base ** np.arange(keys.shape[1], dtype=np.int64))
    _, first, back = np.unique(code, return_index=True, return_inverse=True)
    return keys[first], back


def _starts(slack: np.ndarray, order: np.ndarray) -> dict[int, list[int]]:
    """Robot -> the steps s (ascending) where some window of its path has room (:func:`_slack`), the robots in the
    order of the first step s where ``order`` (T, N) holds."""
    first: dict[int, None] = dict.fromkeys(np.nonzero(order)[1].tolist())
    s, i = np.nonzero(slack.any(axis=2))
    out: dict[int, list[int]] = {robot: [] for robot in first}
    for robot, step in zip(i.tolist(), s.tolist()):
        out[robot].append(step)
    return {robot: steps for robot, steps in out.items() if steps}
