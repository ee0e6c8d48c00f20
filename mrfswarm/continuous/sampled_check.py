"""The dense sampled check of continuous trajectories: separation and obstacles.

Independent of the certificate (which proves the same properties on control points),
this samples all robots on one time grid at ``rate_hz`` (at least 100 Hz): the minimum
distance between any two robots (all pairs, not only neighbours), whether any sample
lies in an occupied cell or off the map, and the distance to the nearest occupied cell.
The continuous stage runs it on the whole flight when ``smoothing.check_rate_hz`` > 0.

Points have d = 2 or 3 coordinates. Separation is measured in the downwash-scaled metric
:math:`\\|(p_i - p_k) \\odot s\\|` (``s = geometry.downwash_scale(d, c)``: z divided by c),
the metric the safety distance is defined in; clearance is the plain distance to the
nearest occupied cell's square or voxel's cube (a robot is a ball for obstacles).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from mrfswarm.geometry import edge_gap
from mrfswarm.maps import OccupancyGrid
from mrfswarm.trajectory.piece_stack import norms

#: Below this many robots, all pairwise distances are computed at once per sample.
_DENSE_PAIRS = 64
#: Samples handled together (bounded memory, small drift per chunk).
_CHUNK = 128


@dataclass(frozen=True)
class SampledCheck:
    """What sampling found (metres, seconds).

    Attributes
    ----------
    min_separation
        Smallest distance between two robots over the samples (downwash-scaled metric).
    pair, time
        The robots and the time of that smallest distance.
    min_clearance
        Smallest distance from a sample to an occupied cell's square or cube (None: no
        obstacle).
    in_obstacle
        (robot, time) of the first sample inside an occupied cell or off the map, or None.
    """

    min_separation: float
    pair: tuple[int, int] | None
    time: float
    min_clearance: float | None
    in_obstacle: tuple[int, float] | None


def uniform_times(t0: float, t1: float, rate_hz: float) -> np.ndarray:
    """Times from t0 to t1 inclusive, spaced at most 1 / rate_hz apart."""
    n = max(2, int(np.ceil((t1 - t0) * rate_hz)) + 1)
    return np.linspace(t0, t1, n)


def min_pair_distance(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per sample of ``points`` (S, N, d): the smallest pairwise distance and its pair (S, 2).

    Exact, without looking at every pair at every sample: within a chunk of samples in
    which no robot moves more than D from its first position, a pair more than
    d_nn + 4 D apart at the chunk's first sample (d_nn: the smallest distance there) is
    more than d_nn + 2 D apart throughout, farther than the first sample's nearest pair
    ever gets, so it is never the closest.
    """
    S, N, _ = points.shape
    if N < 2:
        return np.full(S, np.inf), np.zeros((S, 2), dtype=int)
    dmin = np.empty(S)
    pairs = np.empty((S, 2), dtype=int)
    for a in range(0, S, _CHUNK):
        chunk = points[a:a + _CHUNK]
        if N <= _DENSE_PAIRS:
            iu, ju = np.triu_indices(N, 1)
        else:
            drift = float(np.max(norms(chunk - chunk[:1])))
            d0, _ = cKDTree(chunk[0]).query(chunk[0], 2)
            cand = cKDTree(chunk[0]).query_pairs(float(d0[:, 1].min()) + 4 * drift + 1e-9, output_type="ndarray")
            iu, ju = cand[:, 0], cand[:, 1]
        d = norms(chunk[:, iu] - chunk[:, ju])  # (chunk, pairs)
        k = np.argmin(d, axis=1)
        dmin[a:a + len(chunk)] = d[np.arange(len(chunk)), k]
        pairs[a:a + len(chunk)] = np.stack([iu[k], ju[k]], axis=1)
    return dmin, pairs


def voxel_clearance(occupied: np.ndarray, points: np.ndarray, k: int = 8) -> float | None:
    """Smallest distance (cells) from any point (..., d), in cell coordinates, to an occupied cell's square or cube
    or to the map's edge (off the map counts as a wall, floor and ceiling included); None for no point.

    Exact: a cell whose centre is c from a point is
    between c - sqrt(d)/2 and c from it, so with the ``k`` nearest centres of a point at
    most c_k away, the nearest cell is among them once the best of them is within
    c_k - sqrt(d)/2; points where it is not are asked again with four times as many.
    """
    d = occupied.ndim
    pts = np.asarray(points, dtype=float).reshape(-1, d)
    if not len(pts):
        return None
    best = float(edge_gap(pts, occupied.shape).min())
    cells = np.argwhere(occupied)
    if len(cells) == 0:
        return best
    tree = cKDTree(cells)
    while len(pts):
        kk = min(k, len(cells))
        dist, idx = tree.query(pts, kk)
        dist, idx = np.asarray(dist).reshape(len(pts), kk), np.asarray(idx).reshape(len(pts), kk)
        gap = norms(np.maximum(0.0, np.abs(pts[:, None, :] - cells[idx]) - 0.5)).min(axis=1)
        best = min(best, float(gap.min()))
        if kk == len(cells):
            break
        pts = pts[gap > dist[:, -1] - 0.5 * np.sqrt(d)]  # another cell might be nearer
        k *= 4
    return best


def check_positions(times: np.ndarray, points: np.ndarray, grid: OccupancyGrid,
                    scale: np.ndarray | None = None) -> SampledCheck:
    """Check robots at ``points`` (S, N, d) metres, sampled at ``times`` (S,); separation in the metric
    scaled by ``scale`` (d,) (default: the plain distance)."""
    dmin, pairs = min_pair_distance(points if scale is None else points * np.asarray(scale, dtype=float))
    k = int(np.argmin(dmin))
    pair = (int(min(pairs[k])), int(max(pairs[k]))) if np.isfinite(dmin[k]) else None
    cells = grid.world_to_cell(points)
    inside = ~grid.is_free(cells)  # off the map counts too
    hit = None
    if inside.any():
        s, i = np.argwhere(inside)[0]
        hit = (int(i), float(times[s]))
    cell_pts = (points - np.asarray(grid.origin)) / grid.resolution
    clr = voxel_clearance(grid.occupied, cell_pts)
    return SampledCheck(
        min_separation=float(dmin[k]),
        pair=pair,
        time=float(times[k]),
        min_clearance=None if clr is None else clr * grid.resolution,
        in_obstacle=hit,
    )
