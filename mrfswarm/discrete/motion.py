"""Straight-line motion within one MRF step: obstacle clearance and robot-robot distance.

Within a step every robot moves in a straight line from its cell to its next cell, all
robots at the same time with the same time law. Two facts follow, both used as hard
constraints and checked again on every output:

- Obstacles: a move is allowed only if every cell whose square lies closer than half a
  cell to the segment is free. For a one-cell move this is the segment's own cells (a
  diagonal move needs both cells beside the corner it passes); for longer moves it keeps
  the motion half a cell from every wall, so a tube around it stays out of walls too.
- Robots: for robots i and j with start offset d0 = p_i - p_j and relative motion
  v = o_i - o_j, the distance over the step is |d0 + s v|, s in [0, 1], whose minimum is at
  s* = clip(-d0.v / |v|^2, 0, 1). It must stay >= 1 cell. This does not depend on the
  time law, so it holds for any common time law (the continuous stage relies on this).

All distances here are in cells.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from scipy.spatial import cKDTree

from mrfswarm.geometry import segment_box_distance

#: Robots closer than this within a step collide (cells).
MIN_SEPARATION = 1.0
#: A move needs every cell closer than this to its segment free (cells).
WALL_CLEARANCE = 0.5
_EPS = 1e-9


@lru_cache(maxsize=32)
def stencil(order: int) -> np.ndarray:
    """Offsets (dx, dy) with dx^2 + dy^2 <= order, (0, 0) first, then by length and angle.

    Returns a read-only (S, 2) int array; the order is the label order of every robot.
    """
    r = int(np.floor(np.sqrt(order)))
    dx, dy = np.meshgrid(np.arange(-r, r + 1), np.arange(-r, r + 1), indexing="ij")
    off = np.stack([dx.ravel(), dy.ravel()], axis=1)
    off = off[(off**2).sum(axis=1) <= order]
    key = np.lexsort((np.arctan2(off[:, 1], off[:, 0]), (off**2).sum(axis=1)))
    out = off[key]
    out.setflags(write=False)
    return out


@lru_cache(maxsize=32)
def swept_cells(order: int) -> tuple[np.ndarray, np.ndarray]:
    """For each stencil offset, the relative cells that must be free for that move.

    Returns
    -------
    cells
        (S, K, 2) relative cells, padded by repeating the offset's own cell.
    count
        (S,) number of real entries per offset.
    """
    off = stencil(order)
    r = int(np.ceil(np.sqrt(order))) + 1
    xs, ys = np.meshgrid(np.arange(-r, r + 1), np.arange(-r, r + 1), indexing="ij")
    grid = np.stack([xs.ravel(), ys.ravel()], axis=1)
    per = []
    for o in off:
        d = segment_box_distance(np.zeros(2), o.astype(float), grid.astype(float))
        per.append(grid[d < WALL_CLEARANCE - _EPS])
    K = max(len(p) for p in per)
    cells = np.empty((len(off), K, 2), dtype=np.intp)
    for s, need in enumerate(per):
        arr = np.array(need, dtype=np.intp)
        cells[s, : len(arr)] = arr
        cells[s, len(arr):] = off[s]
    counts = np.array([len(p) for p in per])
    cells.setflags(write=False)
    return cells, counts


def moves_clear(free: np.ndarray, starts: np.ndarray, offsets: np.ndarray, order: int) -> np.ndarray:
    """Whether each move keeps half a cell away from every occupied cell.

    Parameters
    ----------
    free
        (W, H) bool, True for free cells.
    starts
        (N, 2) start cells.
    offsets
        (N, S) indices into ``stencil(order)``.

    Returns
    -------
    (N, S) bool; cells off the map count as occupied.
    """
    cells, _ = swept_cells(order)
    W, H = free.shape
    req = starts[:, None, None, :] + cells[offsets]  # (N, S, K, 2)
    inb = (req[..., 0] >= 0) & (req[..., 0] < W) & (req[..., 1] >= 0) & (req[..., 1] < H)
    x = np.clip(req[..., 0], 0, W - 1)
    y = np.clip(req[..., 1], 0, H - 1)
    return np.all(inb & free[x, y], axis=-1)


@lru_cache(maxsize=4096)
def _swept_by_offset(dx: int, dy: int, clearance: float) -> np.ndarray:
    """Relative cells closer than ``clearance`` to the segment from (0, 0) to (dx, dy), read-only (K, 2)."""
    r = int(np.ceil(clearance)) + 1
    xs, ys = np.meshgrid(np.arange(min(0, dx) - r, max(0, dx) + r + 1), np.arange(min(0, dy) - r, max(0, dy) + r + 1),
                         indexing="ij")
    cells = np.stack([xs.ravel(), ys.ravel()], axis=1)
    d = segment_box_distance(np.zeros(2), np.array([dx, dy], dtype=float), cells.astype(float))
    out = cells[d < clearance - _EPS]
    out.setflags(write=False)
    return out


def segments_clear(free: np.ndarray, starts: np.ndarray, ends: np.ndarray, clearance: float = WALL_CLEARANCE) -> np.ndarray:
    """For straight moves between integer cells, whether every cell closer than ``clearance`` is free.

    The same predicate as :func:`mrfswarm.geometry.segment_clear` for many moves at once:
    the moves are grouped by their offset, whose swept cells are computed once.

    Parameters
    ----------
    free
        (W, H) bool, True for free cells.
    starts, ends
        (M, 2) integer cells.

    Returns
    -------
    (M,) bool; cells off the map count as occupied.
    """
    starts = np.asarray(starts, dtype=np.intp).reshape(-1, 2)
    ends = np.asarray(ends, dtype=np.intp).reshape(-1, 2)
    out = np.ones(len(starts), dtype=bool)
    if not len(starts):
        return out
    W, H = free.shape
    off = ends - starts
    span = int(np.abs(off).max()) * 2 + 1
    key = (off[:, 0] + span // 2) * span + (off[:, 1] + span // 2)
    order = np.argsort(key, kind="stable")
    bounds = np.flatnonzero(np.diff(key[order])) + 1
    for group in np.split(order, bounds):
        rel = _swept_by_offset(int(off[group[0], 0]), int(off[group[0], 1]), float(clearance))
        cells = starts[group][:, None, :] + rel[None]
        inb = (cells[..., 0] >= 0) & (cells[..., 0] < W) & (cells[..., 1] >= 0) & (cells[..., 1] < H)
        ok = inb & free[np.clip(cells[..., 0], 0, W - 1), np.clip(cells[..., 1], 0, H - 1)]
        out[group] = ok.all(axis=1)
    return out


def min_distance_during_move(d0: np.ndarray, v: np.ndarray) -> np.ndarray:
    """min over s in [0, 1] of |d0 + s v|, broadcast over leading axes of (..., 2) arrays."""
    vv = np.einsum("...k,...k->...", v, v)
    s = np.where(vv > _EPS, -np.einsum("...k,...k->...", d0, v) / np.where(vv > _EPS, vv, 1.0), 0.0)
    s = np.clip(s, 0.0, 1.0)
    p = d0 + s[..., None] * v
    return np.hypot(p[..., 0], p[..., 1])


def nearby_pairs(points: np.ndarray, radius: float) -> np.ndarray:
    """(P, 2) pairs i < j of points at distance <= radius, sorted."""
    pairs = cKDTree(points).query_pairs(radius, output_type="ndarray")
    if len(pairs) == 0:
        return np.zeros((0, 2), dtype=np.intp)
    n = np.int64(len(points))
    keys = np.sort(np.minimum(pairs[:, 0], pairs[:, 1]).astype(np.int64) * n + np.maximum(pairs[:, 0], pairs[:, 1]))
    return np.stack([keys // n, keys % n], axis=1).astype(np.intp)


def interaction_radius(order: int) -> float:
    """Robots farther apart than this cannot come within MIN_SEPARATION in one step."""
    return 2.0 * np.sqrt(order) + MIN_SEPARATION


def step_min_separation(p0: np.ndarray, p1: np.ndarray) -> tuple[float, tuple[int, int] | None]:
    """Smallest distance (cells) between any two robots moving straight from p0 to p1.

    Checks all pairs that could come that close (not only graph neighbours).

    Returns
    -------
    (distance, pair); ``(inf, None)`` for a single robot.
    """
    p0 = np.asarray(p0, dtype=float)
    p1 = np.asarray(p1, dtype=float)
    if len(p0) < 2:
        return float("inf"), None
    step = float(np.max(np.hypot(*(p1 - p0).T), initial=0.0))
    # The closest pair during the step starts at most (nearest start distance + 2 step)
    # apart, so these pairs contain it: the answer is exact, not a bound.
    d_nn = float(cKDTree(p0).query(p0, 2)[0][:, 1].min())
    pairs = nearby_pairs(p0, d_nn + 2 * step + 1e-9)
    d0 = p0[pairs[:, 0]] - p0[pairs[:, 1]]
    v = (p1[pairs[:, 0]] - p0[pairs[:, 0]]) - (p1[pairs[:, 1]] - p0[pairs[:, 1]])
    dist = min_distance_during_move(d0, v)
    k = int(np.argmin(dist))
    return float(dist[k]), (int(pairs[k, 0]), int(pairs[k, 1]))
