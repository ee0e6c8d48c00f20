"""Metrics of discrete paths: separation (within steps too), cohesion, clearance, lengths.

Distances are reported in metres. Within a step robots move in straight lines at the same
time (the discrete stage's motion model), so the minimum separation accounts for the
closest approach during every step, over all robot pairs (not only graph neighbours).

Distances over time (:func:`distance_series`) stay near-linear in the swarm size: the
minimum through k-d trees (exact, :func:`min_pair_distances`), the mean over all pairs
exactly up to ``MEAN_PAIRS`` pairs and, for larger swarms, over a fixed uniform sample
of that many pairs (the same pairs at every sample, so the curve is smooth; its
relative standard error is about (std / mean) / sqrt(MEAN_PAIRS), well under 1 %), at
every sample while that takes at most ``MEAN_WORK`` distances and otherwise at evenly
spaced samples, linearly interpolated in between (thousands of samples either way).

Paths are (T + 1, N, d) cells, d = 2 or 3 (voxels), by the same lines. The minimum
separation of discrete paths is measured in the downwash-scaled metric
(:func:`mrfswarm.geometry.downwash_scale`; the plain distance in 2-D or with c = 1), the
one the discrete stage keeps >= 1 cell; obstacle clearance is to the occupied squares or
voxel cubes; path lengths count every axis.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from mrfswarm.discrete.motion import in_grid, step_min_separation
from mrfswarm.geometry import edge_gap, norm, point_box_distance

#: Samples per step when measuring obstacle clearance along straight moves.
_CLEARANCE_SAMPLES = 16
#: Pairs over which the mean inter-robot distance is taken (all pairs up to this many).
MEAN_PAIRS = 20_000
#: Samples of a chunk of :func:`min_pair_distances` (one k-d tree per chunk).
_CHUNK = 64
#: Pair distances the mean of :func:`distance_series` evaluates at most.
MEAN_WORK = 20_000_000


@dataclass(frozen=True)
class DiscreteMetrics:
    """Summary of the discrete paths (metres).

    ``mean_distance`` is over all pairs, or over ``mean_distance_pairs`` random pairs
    when that is not None (large swarms, :func:`distance_series`).
    """

    min_separation: float
    mean_distance: np.ndarray
    min_distance: np.ndarray
    min_obstacle_clearance: float | None
    path_lengths: np.ndarray
    steps: int
    reached_goal: bool | None
    final_goal_distance: float | None
    mean_distance_pairs: int | None = None


def min_separation(paths: np.ndarray, downwash: float = 1.0) -> float:
    """Smallest distance (cells, downwash-scaled metric) between two robots over all steps, during moves included."""
    if paths.shape[1] < 2:
        return float("inf")
    if len(paths) == 1:
        return step_min_separation(paths[0], paths[0], downwash)[0]
    return min(step_min_separation(paths[t], paths[t + 1], downwash)[0] for t in range(len(paths) - 1))


def min_pair_distances(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per sample of ``points`` (S, N, D): the smallest pairwise distance and its pair (S, 2), exactly.

    Never all pairs: within a chunk of samples in which no robot moves more than D from
    its position at the chunk's first sample, a pair more than d_nn + 4 D apart there
    (d_nn: the smallest distance there) stays more than d_nn + 2 D apart, farther than
    the first sample's nearest pair ever gets, so only the pairs a k-d tree returns for
    that radius are measured. A chunk ends before D exceeds half the larger of d_nn and
    the median nearest-neighbour distance (so the radius stays within a few typical
    spacings and the pairs O(N)) or at ``_CHUNK`` samples. Ties go to the first pair in
    lexicographic order.
    """
    points = np.asarray(points, dtype=float)
    S, N, _ = points.shape
    if N < 2:
        return np.full(S, np.inf), np.zeros((S, 2), dtype=np.intp)
    dmin = np.empty(S)
    pairs = np.empty((S, 2), dtype=np.intp)

    def norm(v: np.ndarray) -> np.ndarray:
        return np.sqrt(np.einsum("...k,...k->...", v, v))

    a = 0
    while a < S:
        tree = cKDTree(points[a])
        nn = tree.query(points[a], 2)[0][:, 1]
        d0 = float(nn.min())
        limit = 0.5 * max(d0, float(np.median(nn)))
        reach = np.zeros(0)
        while len(reach) < _CHUNK and (not len(reach) or reach[-1] <= limit) and a + len(reach) < S:
            more = points[a + len(reach):a + min(_CHUNK, max(8, 2 * len(reach)))]  # look ahead in growing blocks
            step = np.max(norm(more - points[a]), axis=1)
            reach = np.maximum.accumulate(np.concatenate([reach, step]))
        m = max(1, int(np.searchsorted(reach, limit, side="right")))
        chunk = points[a:a + m]
        drift = float(reach[m - 1])
        cand = tree.query_pairs(d0 + 4 * drift + 1e-9, output_type="ndarray")
        keys = np.sort(np.minimum(cand[:, 0], cand[:, 1]).astype(np.int64) * N + np.maximum(cand[:, 0], cand[:, 1]))
        cand = np.stack([keys // N, keys % N], axis=1)
        d = norm(chunk[:, cand[:, 0]] - chunk[:, cand[:, 1]])  # (chunk, pairs)
        k = np.argmin(d, axis=1)
        dmin[a:a + m] = d[np.arange(m), k]
        pairs[a:a + m] = cand[k]
        a += m
    return dmin, pairs


def mean_pairs(n: int, max_pairs: int = MEAN_PAIRS, seed: int = 0) -> tuple[np.ndarray, bool]:
    """Robot pairs (P, 2), i < j, over which the mean distance is taken, and whether they are all pairs.

    All pairs when there are at most ``max_pairs``; otherwise ``max_pairs`` distinct pairs
    drawn uniformly (seeded, so the same every time).
    """
    total = n * (n - 1) // 2
    if total <= max_pairs:
        iu, ju = np.triu_indices(n, 1)
        return np.stack([iu, ju], axis=1), True
    rng = np.random.default_rng(seed)
    keys = np.zeros(0, dtype=np.int64)
    while len(keys) < max_pairs:
        i = rng.integers(0, n, 2 * max_pairs)
        j = rng.integers(0, n, 2 * max_pairs)
        ok = i != j
        new = np.minimum(i, j)[ok].astype(np.int64) * n + np.maximum(i, j)[ok]
        keys = np.unique(np.concatenate([keys, new]))
    keys = rng.permutation(keys)[:max_pairs]
    keys.sort()
    return np.stack([keys // n, keys % n], axis=1).astype(np.intp), False


@dataclass(frozen=True)
class DistanceSeries:
    """Inter-robot distances at each sample (units of the input).

    Attributes
    ----------
    min
        (S,) smallest distance between two robots (exact).
    mean
        (S,) mean distance over :attr:`n_pairs` pairs: all pairs when :attr:`exact`.
    exact
        True when the mean is over all pairs; False when over a uniform sample of pairs.
    n_pairs
        Pairs the mean is taken over.
    """

    min: np.ndarray
    mean: np.ndarray
    exact: bool
    n_pairs: int


def distance_series(points: np.ndarray, max_pairs: int = MEAN_PAIRS, max_work: int = MEAN_WORK) -> DistanceSeries:
    """Minimum and mean inter-robot distance at each sample of ``points`` (S, N, d); see the module docstring."""
    points = np.asarray(points, dtype=float)
    S, N, _ = points.shape
    if N < 2:
        return DistanceSeries(np.full(S, np.inf), np.full(S, np.nan), True, 0)
    dmin, _ = min_pair_distances(points)
    pairs, exact = mean_pairs(N, max_pairs)
    # the mean at every sample while that is at most max_work distances, else at evenly
    # spaced samples (every one of them exact or over the same pairs), linear in between
    every = max(1, int(np.ceil(S * len(pairs) / max_work)))
    at = np.unique(np.append(np.arange(0, S, every), S - 1))
    mean = np.empty(len(at))
    step = max(1, 2_000_000 // len(pairs))  # bounded memory
    for a in range(0, len(at), step):
        sel = at[a:a + step]
        d = points[sel][:, pairs[:, 0]] - points[sel][:, pairs[:, 1]]
        mean[a:a + step] = norm(d).mean(axis=1)
    if len(at) < S:
        mean = np.interp(np.arange(S), at, mean)
    return DistanceSeries(dmin, mean, exact, len(pairs))


class ObstacleIndex:
    """Distances to the occupied cells of a grid and to its edge, from a k-d tree built once.

    Parameters
    ----------
    occupied
        (W, H) or (W, H, D) bool, True where occupied.
    """

    def __init__(self, occupied: np.ndarray) -> None:
        self.shape = tuple(occupied.shape)
        self.cells = np.argwhere(occupied)
        self.tree = cKDTree(self.cells) if len(self.cells) else None

    def clearance(self, points: np.ndarray) -> float | None:
        """Smallest distance (cells) from any point (..., d), in cell coordinates, to an occupied square (cube) or
        the map's edge (off the map counts as a wall, floor and ceiling included); None for no point.

        Exact: the nearest squares (cubes) are among the 2^d nearest occupied cell centres (the
        cells around the point's nearest box point).
        """
        ndim = len(self.shape)
        pts = np.asarray(points, dtype=float).reshape(-1, ndim)
        if not len(pts):
            return None
        best = float(edge_gap(pts, self.shape).min())
        if self.tree is None:
            return best
        k = min(8 if ndim == 2 else 27, len(self.cells))
        _, idx = self.tree.query(pts, k)
        idx = np.asarray(idx).reshape(len(pts), k)
        d = point_box_distance(pts[:, None, :], self.cells[idx].astype(float))
        return min(best, float(d.min()))


def obstacle_clearance(occupied: np.ndarray, points: np.ndarray) -> float | None:
    """Smallest distance (cells) from any point (..., d), in cell coordinates, to an occupied square (cube) or the
    map's edge; None for no point. Builds an :class:`ObstacleIndex`; keep one per map when asking many times.
    """
    return ObstacleIndex(occupied).clearance(points)


def densify(paths: np.ndarray, samples: int = _CLEARANCE_SAMPLES) -> np.ndarray:
    """Points along the straight moves of ``paths`` (T + 1, N, d), ``samples`` per step."""
    if len(paths) == 1:
        return paths.astype(float)
    s = np.linspace(0.0, 1.0, samples, endpoint=False)[:, None, None, None]
    a = paths[:-1].astype(float)[None]
    b = paths[1:].astype(float)[None]
    pts = (a + s * (b - a)).transpose(1, 0, 2, 3).reshape(-1, paths.shape[1], paths.shape[2])
    return np.concatenate([pts, paths[-1:].astype(float)])


def path_clearance(paths: np.ndarray, occupied: np.ndarray, samples: int = _CLEARANCE_SAMPLES) -> float | None:
    """Smallest distance (cells) to an occupied square or the map's edge over :func:`densify` (paths, samples).

    Equal to measuring every densified point, without densifying every move: the
    positions themselves (points of the densified set) give an upper bound U, and a move
    from cell p of length L has every point at least edt(p) - L - sqrt(d)/2 from an
    occupied square or cube (edt: the distance from p's centre to the nearest occupied cell
    centre), so only the moves whose bound is below U are densified.
    """
    index = ObstacleIndex(occupied)
    paths = np.asarray(paths)
    upper = index.clearance(paths)
    if upper is None or len(paths) == 1 or not occupied.any():
        # the map's edge is nearest at a move's ends (its distance is concave along a straight move): the
        # positions themselves give it
        return upper
    from scipy.ndimage import distance_transform_edt

    ndim = occupied.ndim
    edt = distance_transform_edt(~occupied)
    p, q = paths[:-1].reshape(-1, ndim), paths[1:].reshape(-1, ndim)
    inb = in_grid(p, occupied.shape)
    e = np.zeros(len(p))
    e[inb] = edt[tuple(p[inb].T)]
    bound = e - norm(q - p) - np.sqrt(ndim / 4)
    near = np.flatnonzero(bound < upper)
    if not len(near):
        return upper
    s = np.linspace(0.0, 1.0, samples, endpoint=False)[:, None, None]
    a, b = p[near].astype(float)[None], q[near].astype(float)[None]
    sampled = index.clearance(a + s * (b - a))
    return upper if sampled is None else min(upper, sampled)


def discrete_metrics(paths: np.ndarray, occupied: np.ndarray, resolution: float = 1.0,
                     goal: np.ndarray | None = None, goal_radius: float | None = None,
                     downwash: float = 1.0, arrived: bool = False) -> DiscreteMetrics:
    """All metrics of discrete paths (T + 1, N, d) in cells, reported in metres.

    ``reached_goal``: the swarm's centroid at the end within ``goal_radius`` metres of the
    goal with a robot there too (a swarm stopped around a goal it cannot reach, the straight-line
    field's robots in front of the walls of an enclosed goal, has its centroid there and no robot),
    or every robot in the goal region (``arrived``: the plan ended by the arrival rule,
    ``mrf.arrival``; a large swarm fills a region wider than ``goal_radius``, and its centroid
    can sit off it); None without a goal. ``downwash``: c of the separation's scaled metric.
    """
    ds = distance_series(paths) if paths.shape[1] > 1 else None
    mean_d = ds.mean if ds is not None else np.full(len(paths), np.nan)
    min_d = ds.min if ds is not None else np.full(len(paths), np.nan)
    clearance = path_clearance(paths, occupied)
    steps = np.diff(paths.astype(float), axis=0)
    lengths = norm(steps).sum(axis=0) * resolution if len(steps) else np.zeros(paths.shape[1])
    reached = dist = None
    if goal is not None:
        dist = float(norm(paths[-1].mean(axis=0) - goal)) * resolution
        nearest = float(norm(paths[-1] - goal).min()) * resolution
        reached = bool(arrived or (goal_radius is not None and dist <= goal_radius and nearest <= goal_radius))
    return DiscreteMetrics(
        min_separation=min_separation(paths, downwash) * resolution,
        mean_distance=mean_d * resolution,
        min_distance=min_d * resolution,
        min_obstacle_clearance=None if clearance is None else clearance * resolution,
        path_lengths=lengths,
        steps=len(paths) - 1,
        reached_goal=reached,
        final_goal_distance=dist,
        mean_distance_pairs=None if ds is None or ds.exact else ds.n_pairs,
    )
