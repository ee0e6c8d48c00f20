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
move midpoints returns for that radius, never against every robot.

Laziness. The greedy walk needs a chord only if every longer chord from the same
waypoint is invalid, and in a dense swarm most chords are (robots follow each other,
so a chord runs through cells a neighbour stands on during the window). So
:func:`prune_paths` first rules out, for all chords of a window at once and cheaply,
those through a cell another robot visits in the window (a lattice point of the chord:
the chord then touches that robot's moves, which end there) and those too near a wall;
it then walks every robot as if the remaining chords were valid, runs the exact test on
the chords walked only, and walks again until every chord walked is proven valid (a
1000-robot crossing: the exact test ran on 28 chords per robot and window, 0.4 now).
:func:`prune_robot` does one robot against the robots whose window bounding box comes
near its own. Both give exactly the waypoints of :func:`prune_paths_brute_force`, the
all-pairs reference the tests hold them to.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from mrfswarm.discrete.motion import WALL_CLEARANCE, segments_clear
from mrfswarm.geometry import norm, segment_clear, segment_segment_distance

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
    d = paths.shape[-1]
    p = paths[a:b, robots].reshape(-1, d).astype(float)
    q = paths[a + 1:b + 1, robots].reshape(-1, d).astype(float)
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
    lo, hi = w.min(axis=0), w.max(axis=0)  # (N, d)
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


class _WindowMoves:
    """The moves of every robot over steps a..b, indexed by their midpoints (built when first needed)."""

    def __init__(self, paths: np.ndarray, a: int, b: int) -> None:
        self.p, self.q, self.owner = _window_segments(paths, np.arange(paths.shape[1]), a, b)
        self.mid, self.half = (self.p + self.q) / 2, norm(self.q - self.p) / 2
        self.tree = cKDTree(self.mid)
        self.reach = float(self.half.max()) + _TOUCH + _SLACK

    def touched(self, cp: np.ndarray, cq: np.ndarray, owner: np.ndarray) -> np.ndarray:
        """(C,) bool: does chord c (ends ``cp``, ``cq``, of robot ``owner[c]``) touch another robot's move?"""
        c_mid, c_half = (cp + cq) / 2, norm(cq - cp) / 2
        sp, sq = self.p, self.q
        ci_parts, si_parts = [], []
        # chords queried in groups of like length, each with its own reach: one global reach set by
        # the longest chord made every short chord meet most of a dense swarm (12 s -> 1 s at 300)
        groups = np.minimum(np.floor(c_half / _CHORD_BIN).astype(np.intp), _CHORD_BINS - 1)
        for g in np.unique(groups):
            idx = np.flatnonzero(groups == g)
            near = cKDTree(c_mid[idx]).sparse_distance_matrix(self.tree, float(c_half[idx].max()) + self.reach,
                                                              output_type="ndarray")
            ci, si = idx[near["i"].astype(np.intp)], near["j"].astype(np.intp)
            keep = (self.owner[si] != owner[ci]) & (near["v"] <= c_half[ci] + self.half[si] + _TOUCH + _SLACK)
            ci, si = ci[keep], si[keep]
            # segments that touch have overlapping bounding boxes (grown by the touching distance)
            keep = np.all((np.minimum(cp[ci], cq[ci]) <= np.maximum(sp[si], sq[si]) + _TOUCH + _SLACK)
                          & (np.minimum(sp[si], sq[si]) <= np.maximum(cp[ci], cq[ci]) + _TOUCH + _SLACK), axis=1)
            ci_parts.append(ci[keep])
            si_parts.append(si[keep])
        ci, si = np.concatenate(ci_parts), np.concatenate(si_parts)
        touch = segment_segment_distance(cp[ci], cq[ci], sp[si], sq[si]) < _TOUCH
        out = np.zeros(len(cp), dtype=bool)
        out[ci[touch]] = True
        return out


def _through_others_cells(paths: np.ndarray, a: int, b: int, cp: np.ndarray, cq: np.ndarray,
                          owner: np.ndarray) -> np.ndarray:
    """(C,) bool: does chord c pass through a cell (a lattice point) another robot is at during steps a..b?

    Such a chord touches that robot's moves (the cell is the end of one), so it is invalid;
    the converse need not hold (a chord can cross a move between cells), so a chord
    without such a cell still needs the exact test. The chord ``cp``..``cq`` between
    integer cells passes through the lattice points ``cp + t (cq - cp) / g``,
    ``t = 0..g``, ``g`` the gcd of the offset's components; the cells are looked up among
    the window's visited cells, each with the one robot visiting it (or a mark for
    several).
    """
    N, ndim = paths.shape[1], paths.shape[2]
    w = paths[a:b + 1].reshape(-1, ndim).astype(np.int64)
    lo = w.min(axis=0)
    # row-major keys over the window's bounding box (a chord's lattice points lie in it)
    dims = w.max(axis=0) - lo + 1
    strides = np.append(np.cumprod(dims[:0:-1])[::-1], 1)

    def key(c: np.ndarray) -> np.ndarray:
        return (c - lo) @ strides

    visits = np.unique(key(w) * N + np.tile(np.arange(N), b - a + 1))  # (cell, robot), sorted by cell then robot
    cells, first, count = np.unique(visits // N, return_index=True, return_counts=True)
    visitor = np.where(count > 1, -1, visits[first] % N)  # the one robot visiting a cell, -1 if several
    d = cq - cp
    g = np.gcd.reduce(np.abs(d), axis=1)  # 0 for a chord of zero length: its one point
    step = d // np.maximum(g, 1)[:, None]
    chord = np.repeat(np.arange(len(cp)), g + 1)
    t = np.arange(len(chord)) - np.repeat(np.cumsum(g + 1) - (g + 1), g + 1)
    k = key(cp[chord] + t[:, None] * step[chord])
    at = np.minimum(np.searchsorted(cells, k), len(cells) - 1)
    hit = (cells[at] == k) & (visitor[at] != owner[chord])
    return np.bincount(chord[hit], minlength=len(cp)) > 0


def _greedy_walk(ok: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The farthest-first walk of every robot through a window, taking chord (k, m) where ``ok[i, k, m]``.

    From each kept waypoint k the walk goes to the largest m >= k + 2 with ``ok``, else to
    k + 1. Returns ``(kept, jumps)``: (N, n) bool kept waypoints, and the (robot, k, m)
    chords taken (3, J).
    """
    N, n = ok.shape[:2]
    rows = np.arange(N)
    kept = np.zeros((N, n), dtype=bool)
    kept[:, 0] = True
    jumps = []
    k = np.zeros(N, dtype=np.intp)
    later = np.arange(n)[None, :]
    while np.any(k < n - 1):
        go = k < n - 1
        jump = ok[rows, np.minimum(k, n - 1)] & (later >= k[:, None] + 2)
        has = jump.any(axis=1) & go
        far = n - 1 - np.argmax(jump[:, ::-1], axis=1)
        jumps.append(np.stack([rows[has], k[has], far[has]]))
        k = np.where(go, np.where(has, far, k + 1), k)
        kept[rows[go], k[go]] = True
    return kept, np.concatenate(jumps, axis=1) if jumps else np.zeros((3, 0), dtype=np.intp)


def prune_paths(paths: np.ndarray, free: np.ndarray, horizon: int) -> list[np.ndarray]:
    """Per robot, the step indices kept after pruning each horizon window.

    Parameters
    ----------
    paths
        (T + 1, N, d) discrete paths in cells.
    free
        (W, H) or (W, H, D) bool grid.
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
    for a, b in horizon_bounds(T, horizon):
        n = b - a + 1
        if n < 3 or N == 0:  # no chord skips a waypoint
            kept[:, a:b + 1] = True
            continue
        # a chord (k, m) of robot i: -1 invalid, 0 not yet decided, 1 valid (m >= k + 2 only)
        state = np.full((N, n, n), -1, dtype=np.int8)
        i, k, m = np.nonzero(np.broadcast_to(np.triu(np.ones((n, n), dtype=bool), 2), (N, n, n)))
        cp, cq = paths[a + k, i].astype(np.int64), paths[a + m, i].astype(np.int64)
        open_ = ~_through_others_cells(paths, a, b, cp, cq, i)
        open_[open_] = segments_clear(free, cp[open_], cq[open_], WALL_CLEARANCE)
        state[i[open_], k[open_], m[open_]] = 0
        moves = None
        while True:  # walk as if every undecided chord were valid; decide the ones walked; until none is left
            walk, jumps = _greedy_walk(state >= 0)
            ji, jk, jm = jumps
            todo = state[ji, jk, jm] == 0
            if not todo.any():
                break
            ji, jk, jm = ji[todo], jk[todo], jm[todo]
            if moves is None:
                moves = _WindowMoves(paths, a, b)
            touched = moves.touched(paths[a + jk, ji].astype(float), paths[a + jm, ji].astype(float), ji)
            state[ji, jk, jm] = np.where(touched, -1, 1)
        kept[:, a:b + 1] |= walk
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
