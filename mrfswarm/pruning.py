"""Waypoint pruning per planning horizon (paper Section IV-C).

"A simple waypoint pruning method would be to connect the endpoints of each resulting
trajectory, unless the pruned path intersects with an obstacle or another robot's
trajectory. This could be performed iteratively." Per robot and per horizon of H steps,
from each kept waypoint we jump to the farthest later waypoint of the horizon whose
straight connection keeps half a cell from every occupied cell (the rule the discrete
moves obey) and crosses no other robot's discrete trajectory in that horizon. The
horizon's ends are always kept, and waypoints stay on their step index (so on the
common time grid).
"""

from __future__ import annotations

import numpy as np

from mrfswarm.geometry import segment_segment_distance, segments_clear
from mrfswarm.motion import WALL_CLEARANCE

_TOUCH = 1e-9


def horizon_bounds(n_steps: int, horizon: int) -> list[tuple[int, int]]:
    """[(a, b), ...] step-index windows of ``horizon`` steps covering 0..n_steps."""
    if horizon < 1:
        raise ValueError(f"horizon must be >= 1, got {horizon}")
    return [(a, min(a + horizon, n_steps)) for a in range(0, max(n_steps, 1), horizon) if a < n_steps] or [(0, 0)]


def _crosses_others(paths: np.ndarray, robot: int, a: int, b: int, p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """(C,) does each segment p_c q_c ((C, 2) ends) meet another robot's discrete trajectory over steps a..b?"""
    others = np.delete(np.arange(paths.shape[1]), robot)
    if len(others) == 0:
        return np.zeros(len(p), dtype=bool)
    seg_p = paths[a:b, others].reshape(-1, 2).astype(float)
    seg_q = paths[a + 1 : b + 1, others].reshape(-1, 2).astype(float)
    if len(seg_p) == 0:  # a one-point window: the others' positions
        seg_p = seg_q = paths[a, others].astype(float)
    d = segment_segment_distance(p[:, None, :], q[:, None, :], seg_p[None], seg_q[None])
    return np.any(d < _TOUCH, axis=1)


def prune_robot(paths: np.ndarray, free: np.ndarray, robot: int, a: int, b: int) -> list[int]:
    """Kept step indices of ``robot`` within window [a, b] (both ends kept)."""
    P = paths[:, robot].astype(float)
    if np.all(P[a:b + 1] == P[a]):
        # At rest through the window: the ends join by a point, in a free cell no other
        # robot's move comes within a cell of (the discrete invariant); the loop below
        # would keep [a, b] too.
        return [a, b] if b > a else [a]
    kept = [a]
    k = a
    while k < b:
        far = np.arange(b, k + 1, -1)  # farthest first
        start = np.broadcast_to(P[k], (len(far), 2))
        ok = segments_clear(free, start, P[far], WALL_CLEARANCE)
        if ok.any():
            ok[ok] = ~_crosses_others(paths, robot, a, b, start[ok], P[far[ok]])
        nxt = int(far[np.argmax(ok)]) if ok.any() else k + 1
        kept.append(nxt)
        k = nxt
    return kept


def prune_paths(paths: np.ndarray, free: np.ndarray, horizon: int) -> list[np.ndarray]:
    """Per robot, the step indices kept after pruning each horizon window.

    Parameters
    ----------
    paths
        (T + 1, N, 2) discrete paths in cells.
    free
        (W, H) bool grid.
    horizon
        H, steps per planning horizon.

    Returns
    -------
    One sorted int array per robot, starting at 0 and ending at T; every window boundary
    (multiples of H, and T) is kept.
    """
    T = paths.shape[0] - 1
    out = []
    for i in range(paths.shape[1]):
        kept: list[int] = [0]
        for a, b in horizon_bounds(T, horizon):
            kept += prune_robot(paths, free, i, a, b)[1:]
        out.append(np.array(kept, dtype=np.intp))
    return out
