"""Checks of the discrete safety invariants, run on every plan before it is returned.

Discrete: at every step no two robots share a cell, no robot is in an occupied cell or
off the map, every straight move keeps half a cell from occupied cells, and robots moving
straight at the same time stay at least one cell apart during each step (all pairs,
not only interaction-graph neighbours).
"""

from __future__ import annotations

import numpy as np

from mrfswarm.geometry import segments_clear
from mrfswarm.motion import MIN_SEPARATION, WALL_CLEARANCE, step_min_separation


def discrete_violations(paths: np.ndarray, free: np.ndarray, limit: int = 10) -> list[str]:
    """Human-readable violations of the discrete invariants (empty when safe).

    Parameters
    ----------
    paths
        (T + 1, N, 2) cells.
    free
        (W, H) bool grid.
    limit
        Stop after this many findings.
    """
    out: list[str] = []
    W, H = free.shape
    for t, p in enumerate(paths):
        inb = (p[:, 0] >= 0) & (p[:, 0] < W) & (p[:, 1] >= 0) & (p[:, 1] < H)
        for i in np.flatnonzero(~inb):
            out.append(f"step {t}: robot {i} off the map at cell {tuple(p[i])}")
        ok = inb.copy()
        ok[inb] = free[p[inb, 0], p[inb, 1]]
        for i in np.flatnonzero(inb & ~ok):
            out.append(f"step {t}: robot {i} in an occupied cell {tuple(p[i])}")
        _, first, counts = np.unique(p, axis=0, return_index=True, return_counts=True)
        for f in first[counts > 1]:
            out.append(f"step {t}: two robots share cell {tuple(p[f])}")
        if t > 0:
            moved = np.flatnonzero(np.any(paths[t - 1] != p, axis=1))
            clear = segments_clear(free, paths[t - 1][moved], p[moved], WALL_CLEARANCE)
            for i in moved[~clear]:
                out.append(f"step {t}: robot {i}'s move {tuple(paths[t - 1][i])} -> {tuple(p[i])} cuts an obstacle")
            d, pair = step_min_separation(paths[t - 1], p)
            if d < MIN_SEPARATION - 1e-9:
                out.append(f"step {t}: robots {pair} come {d:.3f} cells close while moving")
        if len(out) >= limit:
            break
    return out[:limit]
