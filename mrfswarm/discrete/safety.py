"""Checks of the discrete safety invariants, run on every plan before it is returned.

Discrete: at every step no two robots share a cell, no robot is in an occupied cell or
off the map, every straight move keeps half a cell from occupied cells (squares, or voxel
cubes in 3-D), and robots moving straight at the same time stay at least one cell apart
during each step (all pairs, not only interaction-graph neighbours) in the
downwash-scaled metric (:func:`mrfswarm.geometry.downwash_scale`, c = ``downwash``: with
c = 2 no robot may be in, or pass through, the voxel right above another). Paths are
(T + 1, N, d) cells, d = 2 or 3. At step 0 the separation of the start is checked too
(a pair of robots too close at rest).

The check is exact and local. Two robots whose start cells are more than
``MIN_SEPARATION + 2 s`` apart (s: the longest move of the step) stay more than
``MIN_SEPARATION`` apart throughout the step (each end moves at most s), so a step's
pairs are found with a k-d tree query of that radius, never all pairs; the closest
pair of a step that violates the separation is among them, so the messages are those of
the all-pairs check :func:`discrete_violations_brute_force` (tested equal). Obstacle
clearance of the moves is evaluated per distinct move offset
(:func:`mrfswarm.discrete.motion.segments_clear`). The cost is O(T N log N).
"""

from __future__ import annotations

import numpy as np

from mrfswarm.discrete.motion import (
    MIN_SEPARATION,
    WALL_CLEARANCE,
    in_grid,
    min_distance_during_move,
    nearby_pairs,
    scaled,
    segments_clear,
)
from mrfswarm.geometry import norm, segment_clear

_TOL = 1e-9


def _closest_during_step(p0: np.ndarray, p1: np.ndarray, pairs: np.ndarray) -> tuple[float, tuple[int, int] | None]:
    """Smallest distance during the step over ``pairs`` (sorted i < j) and the first pair attaining it."""
    if not len(pairs):
        return float("inf"), None
    d0 = p0[pairs[:, 0]] - p0[pairs[:, 1]]
    v = (p1[pairs[:, 0]] - p0[pairs[:, 0]]) - (p1[pairs[:, 1]] - p0[pairs[:, 1]])
    dist = min_distance_during_move(d0, v)
    k = int(np.argmin(dist))
    return float(dist[k]), (int(pairs[k, 0]), int(pairs[k, 1]))


def _cell(c: np.ndarray) -> str:
    """A cell as ``(x, y)`` or ``(x, y, z)``: a tuple of NumPy integers printed as "(np.int64(11), np.int64(11))"
    (a library tour)."""
    return f"({', '.join(str(int(v)) for v in c)})"


def _step_messages(t: int, p: np.ndarray, inb: np.ndarray, occupied_at: np.ndarray, shared, cut,
                   prev: np.ndarray | None, closest: tuple[float, tuple[int, int] | None]) -> list[str]:
    """One step's findings in a fixed order: off the map, occupied, shared, cuts, separation."""
    out = [f"step {t}: robot {i} off the map at cell {_cell(p[i])}" for i in np.flatnonzero(~inb)]
    out += [f"step {t}: robot {i} in an occupied cell {_cell(p[i])}" for i in np.flatnonzero(occupied_at)]
    out += [f"step {t}: two robots share cell {_cell(p[f])}" for f in shared]
    if prev is not None:
        out += [f"step {t}: robot {i}'s move {_cell(prev[i])} -> {_cell(p[i])} cuts an obstacle" for i in cut]
    d, pair = closest
    if d < MIN_SEPARATION - _TOL and (prev is not None or d > 0):  # at rest, d = 0 is a shared cell (above)
        what = "while moving" if prev is not None else "at the start"
        out.append(f"step {t}: robots {pair} come {d:.3f} cells close {what} (downwash-scaled metric)")
    return out


def _on_map(p: np.ndarray, free: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(in bounds, in bounds and in an occupied cell) per robot."""
    inb = in_grid(p, free.shape)
    occ = np.zeros(len(p), dtype=bool)
    occ[inb] = ~free[tuple(p[inb].T)]
    return inb, occ


def discrete_violations(paths: np.ndarray, free: np.ndarray, limit: int = 10, downwash: float = 1.0) -> list[str]:
    """Human-readable violations of the discrete invariants (empty when safe); see the module docstring.

    Parameters
    ----------
    paths
        (T + 1, N, d) cells.
    free
        (W, H) or (W, H, D) bool grid.
    limit
        Stop after this many findings.
    downwash
        c >= 1: the separation is measured with z divided by c (3-D).
    """
    paths = np.asarray(paths)
    if paths.ndim != 3 or paths.shape[-1] != np.ndim(free):  # (T + 1, N) paths: "'numpy.int64' object is not iterable"
        raise ValueError(f"paths must have shape (T + 1, N, {np.ndim(free)}) (cells on the {np.ndim(free)}-D grid), "
                         f"got {paths.shape}")
    out: list[str] = []
    for t, p in enumerate(paths):
        inb, occ = _on_map(p, free)
        # shared cells: runs of equal cell keys, by cell (x, then y, then z), first occurrence first
        lo = p.min(axis=0)
        rel = (p - lo).astype(np.int64)
        key = np.ravel_multi_index(tuple(rel.T), tuple(rel.max(axis=0) + 1)).astype(np.int64)
        order = np.argsort(key, kind="stable")
        ks = key[order]
        run = np.flatnonzero(np.concatenate([[True], ks[1:] != ks[:-1]]))
        shared = order[run[np.diff(np.append(run, len(ks))) > 1]]
        prev = cut = None
        closest: tuple[float, tuple[int, int] | None] = (float("inf"), None)
        q0 = q1 = scaled(p, downwash)
        if t > 0:
            prev = paths[t - 1]
            moved = np.flatnonzero(np.any(prev != p, axis=1))
            cut = moved[~segments_clear(free, prev[moved], p[moved], WALL_CLEARANCE)]
            q0 = scaled(prev, downwash)
        if len(p) > 1:
            step = float(np.max(norm(q1 - q0), initial=0.0))
            closest = _closest_during_step(q0, q1, nearby_pairs(q0, MIN_SEPARATION + 2 * step + _TOL))
        out += _step_messages(t, p, inb, occ, shared, cut, prev, closest)
        if len(out) >= limit:
            break
    return out[:limit]


def discrete_violations_brute_force(paths: np.ndarray, free: np.ndarray, limit: int = 10,
                                    downwash: float = 1.0) -> list[str]:
    """:func:`discrete_violations` the plain way: every pair of robots, one move at a time.

    O(T N^2); the reference the tests hold the indexed check to.
    """
    paths = np.asarray(paths)
    out: list[str] = []
    for t, p in enumerate(paths):
        inb, occ = _on_map(p, free)
        _, first, counts = np.unique(p, axis=0, return_index=True, return_counts=True)
        prev = cut = None
        q0 = scaled(p, downwash)
        if t > 0:
            prev = paths[t - 1]
            moved = np.flatnonzero(np.any(prev != p, axis=1))
            cut = [i for i in moved if not segment_clear(free, prev[i], p[i], WALL_CLEARANCE)]
            q0 = scaled(prev, downwash)
        iu, ju = np.triu_indices(len(p), 1)
        closest = _closest_during_step(q0, scaled(p, downwash), np.stack([iu, ju], axis=1))
        out += _step_messages(t, p, inb, occ, first[counts > 1], cut, prev, closest)
        if len(out) >= limit:
            break
    return out[:limit]
