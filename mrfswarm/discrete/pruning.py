"""Waypoint pruning per planning horizon (paper Section IV-C).

"A simple waypoint pruning method would be to connect the endpoints of each resulting
trajectory, unless the pruned path intersects with an obstacle or another robot's
trajectory. This could be performed iteratively." Per robot and per horizon of H steps,
from each kept waypoint we jump to the farthest later waypoint of the horizon whose
straight connection keeps half a cell from every occupied cell (the rule the discrete
moves obey) and crosses no other robot's discrete trajectory in that horizon. The
horizon's ends are always kept, and waypoints stay on their step index (so on the
common time grid).

Locality. A chord of robot i and a move of robot j can touch only if their midpoints are
at most half the chord's length plus half the move's length apart (triangle
inequality), so each chord is tested against the moves a k-d tree over the window's
move midpoints returns for that radius, never against every robot. :func:`prune_paths`
evaluates every chord of every robot of a window in whole-array operations and then
runs the greedy choice for all robots at once; :func:`prune_robot` does one robot
against the robots whose window bounding box comes near its own. Both give exactly the
waypoints of :func:`prune_paths_brute_force`, the all-pairs reference the tests hold them
to.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from mrfswarm.discrete.motion import WALL_CLEARANCE, segments_clear
from mrfswarm.geometry import segment_clear, segment_segment_distance

_TOUCH = 1e-9
#: Slack on the k-d tree search radius (the exact distance test decides).
_SLACK = 1e-6
#: Chords are queried in groups of half-lengths [0, 0.5), [0.5, 1), ... (cells), the last open-ended.
_CHORD_BIN = 0.5
_CHORD_BINS = 16


def horizon_bounds(n_steps: int, horizon: int) -> list[tuple[int, int]]:
    """[(a, b), ...] step-index windows of ``horizon`` steps covering 0..n_steps."""
    if horizon < 1:
        raise ValueError(f"horizon must be >= 1, got {horizon}")
    return [(a, min(a + horizon, n_steps)) for a in range(0, max(n_steps, 1), horizon) if a < n_steps] or [(0, 0)]


def _window_segments(paths: np.ndarray, robots: np.ndarray, a: int, b: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The moves of ``robots`` over steps a..b: (ends p, ends q, owner robot), as floats."""
    if b == a:  # a one-point window: the robots' positions
        p = paths[a, robots].astype(float)
        return p, p, robots
    p = paths[a:b, robots].reshape(-1, 2).astype(float)
    q = paths[a + 1:b + 1, robots].reshape(-1, 2).astype(float)
    return p, q, np.tile(robots, b - a)


def _crosses_others(paths: np.ndarray, robot: int, a: int, b: int, p: np.ndarray, q: np.ndarray,
                    others: np.ndarray | None = None) -> bool:
    """Does segment pq meet the discrete trajectory of another robot (of ``others``, default all) over steps a..b?"""
    if others is None:
        others = np.delete(np.arange(paths.shape[1]), robot)
    others = others[others != robot]
    if len(others) == 0:
        return False
    seg_p, seg_q, _ = _window_segments(paths, others, a, b)
    d = segment_segment_distance(p[None, :], q[None, :], seg_p, seg_q)
    return bool(np.any(d < _TOUCH))


def _near_robots(paths: np.ndarray, robot: int, a: int, b: int) -> np.ndarray:
    """Robots whose positions over steps a..b have a bounding box within touching distance of ``robot``'s."""
    w = paths[a:b + 1].astype(float)
    lo, hi = w.min(axis=0), w.max(axis=0)  # (N, 2)
    gap = np.maximum(lo - hi[robot], lo[robot] - hi).max(axis=1)
    near = np.flatnonzero(gap < _TOUCH + _SLACK)
    return near[near != robot]


def prune_robot(paths: np.ndarray, free: np.ndarray, robot: int, a: int, b: int) -> list[int]:
    """Kept step indices of ``robot`` within window [a, b] (both ends kept).

    Chords are tested against the robots whose window bounding box comes near this
    robot's (a chord lies in its robot's box, a move in its own).
    """
    P = paths[:, robot].astype(float)
    others = _near_robots(paths, robot, a, b)
    kept = [a]
    k = a
    while k < b:
        nxt = k + 1
        for m in range(b, k + 1, -1):  # farthest first
            if segment_clear(free, P[k], P[m], WALL_CLEARANCE) and not _crosses_others(paths, robot, a, b, P[k], P[m],
                                                                                         others):
                nxt = m
                break
        kept.append(nxt)
        k = nxt
    return kept


def _window_valid(paths: np.ndarray, free: np.ndarray, a: int, b: int) -> np.ndarray:
    """(N, b - a + 1, b - a + 1) bool: may robot i jump from step k to step m (m >= k + 2) in window [a, b]?"""
    N = paths.shape[1]
    n = b - a + 1
    valid = np.zeros((N, n, n), dtype=bool)
    ks, ms = np.nonzero(np.triu(np.ones((n, n), dtype=bool), 2))
    if not len(ks) or N == 0:
        return valid
    robots = np.arange(N)
    # every chord of every robot: (robot, chord) flattened robot-major
    cp = paths[a + ks][:, robots].transpose(1, 0, 2).reshape(-1, 2)
    cq = paths[a + ms][:, robots].transpose(1, 0, 2).reshape(-1, 2)
    owner = np.repeat(robots, len(ks))
    ok = segments_clear(free, cp, cq, WALL_CLEARANCE)
    cand = np.flatnonzero(ok)
    if len(cand) and N > 1:
        sp, sq, sown = _window_segments(paths, robots, a, b)
        cpf, cqf = cp[cand].astype(float), cq[cand].astype(float)
        c_mid, c_half = (cpf + cqf) / 2, np.hypot(*(cqf - cpf).T) / 2
        s_mid, s_half = (sp + sq) / 2, np.hypot(*(sq - sp).T) / 2
        s_tree, s_reach = cKDTree(s_mid), float(s_half.max()) + _TOUCH + _SLACK
        ci_parts, si_parts = [], []
        # chords queried in groups of like length, each with its own reach: one global reach set by
        # the longest chord made every short chord meet most of a dense swarm (12 s -> 1 s at 300)
        groups = np.minimum(np.floor(c_half / _CHORD_BIN).astype(np.intp), _CHORD_BINS - 1)
        for g in np.unique(groups):
            idx = np.flatnonzero(groups == g)
            near = cKDTree(c_mid[idx]).sparse_distance_matrix(s_tree, float(c_half[idx].max()) + s_reach,
                                                              output_type="ndarray")
            ci, si = idx[near["i"].astype(np.intp)], near["j"].astype(np.intp)
            keep = (sown[si] != owner[cand[ci]]) & (near["v"] <= c_half[ci] + s_half[si] + _TOUCH + _SLACK)
            ci, si = ci[keep], si[keep]
            # segments that touch have overlapping bounding boxes (grown by the touching distance)
            keep = np.all((np.minimum(cpf[ci], cqf[ci]) <= np.maximum(sp[si], sq[si]) + _TOUCH + _SLACK)
                          & (np.minimum(sp[si], sq[si]) <= np.maximum(cpf[ci], cqf[ci]) + _TOUCH + _SLACK), axis=1)
            ci_parts.append(ci[keep])
            si_parts.append(si[keep])
        ci, si = np.concatenate(ci_parts), np.concatenate(si_parts)
        touch = segment_segment_distance(cpf[ci], cqf[ci], sp[si], sq[si]) < _TOUCH
        crossed = np.zeros(len(cand), dtype=bool)
        crossed[ci[touch]] = True
        ok[cand[crossed]] = False
    valid[owner, np.tile(ks, N), np.tile(ms, N)] = ok
    return valid


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
    T, N = paths.shape[0] - 1, paths.shape[1]
    kept = np.zeros((N, T + 1), dtype=bool)
    kept[:, 0] = True
    rows = np.arange(N)
    for a, b in horizon_bounds(T, horizon):
        valid = _window_valid(paths, free, a, b)
        n = b - a + 1
        k = np.zeros(N, dtype=np.intp)  # current waypoint, relative to a
        later = np.arange(n)[None, :]
        while np.any(k < n - 1):
            go = k < n - 1
            jump = valid[rows, k] & (later >= k[:, None] + 2)
            far = np.where(jump.any(axis=1), n - 1 - np.argmax(jump[:, ::-1], axis=1), k + 1)
            k = np.where(go, far, k)
            kept[rows[go], a + k[go]] = True
    return [np.flatnonzero(r) for r in kept]


def prune_paths_brute_force(paths: np.ndarray, free: np.ndarray, horizon: int) -> list[np.ndarray]:
    """:func:`prune_paths` the plain way: every chord against every other robot's moves.

    O(N^2) per window; the reference the tests hold the indexed pruning to.
    """
    T = paths.shape[0] - 1
    out = []
    for i in range(paths.shape[1]):
        kept: list[int] = [0]
        for a, b in horizon_bounds(T, horizon):
            P = paths[:, i].astype(float)
            k = a
            while k < b:
                nxt = k + 1
                for m in range(b, k + 1, -1):
                    if segment_clear(free, P[k], P[m], WALL_CLEARANCE) and not _crosses_others(paths, i, a, b, P[k], P[m]):
                        nxt = m
                        break
                kept.append(nxt)
                k = nxt
        out.append(np.array(kept, dtype=np.intp))
    return out
