"""Straight-line motion within one MRF step: obstacle clearance and robot-robot distance.

Within a step every robot moves in a straight line from its cell to its next cell, all
robots at the same time with the same time law. Two facts follow, both used as hard
constraints and checked again on every output:

- Obstacles: a move is allowed only if every cell whose square (voxel: cube) lies closer
  than half a cell to the segment is free. For a one-cell move this is the segment's own
  cells (a diagonal move needs both cells beside the corner it passes; in 3-D a
  face-diagonal move the two voxels beside the edge it passes, a space-diagonal move all
  8 voxels of the 2 x 2 x 2 block it crosses: no corner or edge is cut); for longer moves
  it keeps the motion half a cell from every wall, so a tube around it stays out of walls
  too.
- Robots: for robots i and j with start offset d0 = p_i - p_j and relative motion
  v = o_i - o_j, the distance over the step is |d0 + s v|, s in [0, 1], whose minimum is at
  s* = clip(-d0.v / |v|^2, 0, 1). It must stay >= 1 cell in the downwash-scaled metric
  (:func:`mrfswarm.geometry.downwash_scale`: z divided by c = ``scenario.downwash`` in
  3-D; the plain distance in 2-D or with c = 1), so with c = 2 no robot is ever in the
  voxel right above another, nor passes through it. The scaled distance is the same
  formula on scaled d0 and v. This does not depend on the time law, so it holds for any
  common time law (the continuous stage relies on this).

All distances here are in cells. Cells are (..., d) integer arrays, d = 2 or 3; the
stencil of order n in d dimensions is every offset with squared length <= n (in 3-D,
n = 3 is the 26-neighbourhood).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from scipy.spatial import cKDTree

from mrfswarm.geometry import downwash_scale, norm, segment_box_distance

#: Robots closer than this within a step collide (cells).
MIN_SEPARATION = 1.0
#: A move needs every cell closer than this to its segment free (cells).
WALL_CLEARANCE = 0.5
_EPS = 1e-9


@lru_cache(maxsize=32)
def stencil(order: int, ndim: int = 2) -> np.ndarray:
    """Offsets with squared length <= order, (0, ..., 0) first, then by squared length and direction.

    In the plane the direction order is the angle; in space it is the azimuth, then the
    elevation. Returns a read-only (S, ndim) int array; the order is the label order of
    every robot.
    """
    r = int(np.floor(np.sqrt(order)))
    axes = np.meshgrid(*([np.arange(-r, r + 1)] * ndim), indexing="ij")
    off = np.stack([x.ravel() for x in axes], axis=1)
    off = off[(off**2).sum(axis=1) <= order]
    keys = [np.arctan2(off[:, 1], off[:, 0])]
    if ndim == 3:
        keys.insert(0, np.arctan2(off[:, 2], np.hypot(off[:, 0], off[:, 1])))
    key = np.lexsort((*keys, (off**2).sum(axis=1)))
    out = off[key]
    out.setflags(write=False)
    return out


@lru_cache(maxsize=32)
def swept_cells(order: int, ndim: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """For each stencil offset, the relative cells that must be free for that move.

    Returns
    -------
    cells
        (S, K, ndim) relative cells, padded by repeating the offset's own cell.
    count
        (S,) number of real entries per offset.
    """
    off = stencil(order, ndim)
    r = int(np.ceil(np.sqrt(order))) + 1
    axes = np.meshgrid(*([np.arange(-r, r + 1)] * ndim), indexing="ij")
    grid = np.stack([x.ravel() for x in axes], axis=1)
    per = []
    for o in off:
        d = segment_box_distance(np.zeros(ndim), o.astype(float), grid.astype(float))
        per.append(grid[d < WALL_CLEARANCE - _EPS])
    K = max(len(p) for p in per)
    cells = np.empty((len(off), K, ndim), dtype=np.intp)
    for s, need in enumerate(per):
        arr = np.array(need, dtype=np.intp)
        cells[s, : len(arr)] = arr
        cells[s, len(arr):] = off[s]
    counts = np.array([len(p) for p in per])
    cells.setflags(write=False)
    return cells, counts


@lru_cache(maxsize=32)
def _swept_union(order: int, ndim: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """The cells any move of the stencil needs, once each, and every move's needs as indices into them.

    Returns
    -------
    union
        (U, ndim) relative cells (in 3-D at n = 3: the 27 of the 3 x 3 x 3 block).
    need
        (S, K) index into ``union`` of each entry of :func:`swept_cells` (padding included).
    """
    cells, _ = swept_cells(order, ndim)
    union, need = np.unique(cells.reshape(-1, ndim), axis=0, return_inverse=True)
    need = need.reshape(cells.shape[:2])
    union.setflags(write=False)
    need.setflags(write=False)
    return union, need


def cell_values(grid: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """``grid`` at integer cells (..., d): ``grid[cells[..., 0], ..., cells[..., d - 1]]``."""
    return grid[tuple(np.moveaxis(np.asarray(cells), -1, 0))]


def in_grid(cells: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    """(...,) bool: integer cells (..., d) inside a grid of ``shape``."""
    return np.all((cells >= 0) & (cells < np.asarray(shape)), axis=-1)


def clip_cells(cells: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    """Integer cells (..., d) clipped into a grid of ``shape`` (for safe look-ups beside :func:`in_grid`)."""
    return np.clip(cells, 0, np.asarray(shape) - 1)


def moves_clear(free: np.ndarray, starts: np.ndarray, offsets: np.ndarray, order: int) -> np.ndarray:
    """Whether each move keeps half a cell away from every occupied cell.

    Parameters
    ----------
    free
        (W, H) or (W, H, D) bool, True for free cells.
    starts
        (N, d) start cells.
    offsets
        (N, S) indices into ``stencil(order, d)``.

    Returns
    -------
    (N, S) bool; cells off the map count as occupied.
    """
    # each cell around a robot is looked up once (U of them), and each move's K needs are
    # gathered from those: one grid lookup per cell, not one per move and cell
    union, need = _swept_union(order, free.ndim)
    N = len(starts)
    req = starts[:, None, :] + union  # (N, U, d)
    clear = in_grid(req, free.shape) & cell_values(free, clip_cells(req, free.shape))
    idx = need[offsets].reshape(N, -1)  # (N, S * K)
    return np.asarray(np.take_along_axis(clear, idx, axis=1).reshape(N, offsets.shape[1], need.shape[1]).all(axis=-1))


@lru_cache(maxsize=4096)
def _swept_by_offset(offset: tuple[int, ...], clearance: float) -> np.ndarray:
    """Relative cells closer than ``clearance`` to the segment from the origin to ``offset``, read-only (K, d)."""
    r = int(np.ceil(clearance)) + 1
    axes = np.meshgrid(*(np.arange(min(0, o) - r, max(0, o) + r + 1) for o in offset), indexing="ij")
    cells = np.stack([x.ravel() for x in axes], axis=1)
    d = segment_box_distance(np.zeros(len(offset)), np.array(offset, dtype=float), cells.astype(float))
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
        (W, H) or (W, H, D) bool, True for free cells.
    starts, ends
        (M, d) integer cells.

    Returns
    -------
    (M,) bool; cells off the map count as occupied.
    """
    ndim = free.ndim
    starts = np.asarray(starts, dtype=np.intp).reshape(-1, ndim)
    ends = np.asarray(ends, dtype=np.intp).reshape(-1, ndim)
    out = np.ones(len(starts), dtype=bool)
    if not len(starts):
        return out
    off = ends - starts
    span = int(np.abs(off).max()) * 2 + 1
    key = np.ravel_multi_index(tuple((off + span // 2).T), (span,) * ndim)
    order = np.argsort(key, kind="stable")
    bounds = np.flatnonzero(np.diff(key[order])) + 1
    for group in np.split(order, bounds):
        rel = _swept_by_offset(tuple(int(v) for v in off[group[0]]), float(clearance))
        cells = starts[group][:, None, :] + rel[None]
        ok = in_grid(cells, free.shape) & cell_values(free, clip_cells(cells, free.shape))
        out[group] = ok.all(axis=1)
    return out


def min_distance_during_move(d0: np.ndarray, v: np.ndarray) -> np.ndarray:
    """min over s in [0, 1] of |d0 + s v|, broadcast over leading axes of (..., d) arrays.

    For the downwash-scaled distance pass d0 and v multiplied by
    :func:`~mrfswarm.geometry.downwash_scale` (the metric is linear in them).
    """
    vv = np.einsum("...k,...k->...", v, v)
    s = np.where(vv > _EPS, -np.einsum("...k,...k->...", d0, v) / np.where(vv > _EPS, vv, 1.0), 0.0)
    s = np.clip(s, 0.0, 1.0)
    p = d0 + s[..., None] * v
    return norm(p)


def nearby_pairs(points: np.ndarray, radius: float) -> np.ndarray:
    """(P, 2) pairs i < j of points at distance <= radius, sorted."""
    pairs = cKDTree(points).query_pairs(radius, output_type="ndarray")
    if len(pairs) == 0:
        return np.zeros((0, 2), dtype=np.intp)
    n = np.int64(len(points))
    keys = np.sort(np.minimum(pairs[:, 0], pairs[:, 1]).astype(np.int64) * n + np.maximum(pairs[:, 0], pairs[:, 1]))
    return np.stack([keys // n, keys % n], axis=1).astype(np.intp)


def interaction_radius(order: int) -> float:
    """Robots farther apart than this (in the downwash-scaled metric) cannot come within MIN_SEPARATION in one step.

    A move is at most sqrt(order) cells long, and scaling never lengthens it.
    """
    return 2.0 * np.sqrt(order) + MIN_SEPARATION


def scaled(points: np.ndarray, downwash: float = 1.0) -> np.ndarray:
    """Positions (..., d) in the downwash-scaled space (float): z / c in 3-D, unchanged in 2-D."""
    points = np.asarray(points, dtype=float)
    return points * downwash_scale(points.shape[-1], downwash)


def step_min_separation(p0: np.ndarray, p1: np.ndarray, downwash: float = 1.0) -> tuple[float, tuple[int, int] | None]:
    """Smallest distance (cells, downwash-scaled metric) between any two robots moving straight from p0 to p1.

    Checks all pairs that could come that close (not only graph neighbours).

    Returns
    -------
    (distance, pair); ``(inf, None)`` for a single robot.
    """
    c0, c1 = np.asarray(p0, dtype=float), np.asarray(p1, dtype=float)
    q0, q1 = scaled(c0, downwash), scaled(c1, downwash)
    if len(q0) < 2:
        return float("inf"), None
    step = float(np.max(norm(q1 - q0), initial=0.0))
    # The closest pair during the step starts at most (nearest start distance + 2 step)
    # apart, so these pairs contain it: the answer is exact, not a bound.
    d_nn = float(cKDTree(q0).query(q0, 2)[0][:, 1].min())
    pairs = nearby_pairs(q0, d_nn + 2 * step + 1e-9)
    i, j = pairs[:, 0], pairs[:, 1]
    # cells subtracted, then scaled, as the step's conflict table does: positions scaled first left float noise
    # (robots 3 voxels apart at downwash 3: 0.9999999999999999 cells in result.json, a 3-D tour)
    d0 = scaled(c0[i] - c0[j], downwash)
    v = scaled((c1[i] - c0[i]) - (c1[j] - c0[j]), downwash)
    dist = min_distance_during_move(d0, v)
    k = int(np.argmin(dist))
    return float(dist[k]), (int(pairs[k, 0]), int(pairs[k, 1]))
