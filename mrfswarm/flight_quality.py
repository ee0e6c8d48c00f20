"""What a user feels of a flight: makespan over its dynamic lower bound, stops, speed.

The lower bound of a flight is the time the slowest robot needs at best: the longest,
over robots, of the shortest free path from its start cell to its final cell (the
8-connected grid graph without corner cutting, the moves the discrete stage can make; on
voxels the 26-connected graph without edge or corner cutting), flown at ``v_max``. No plan that moves robots between those cells can end sooner.

A **stop** is a robot slower than :data:`STOP_SPEED` somewhere strictly inside its own
flight: after it first exceeds that speed and before it last does (the departure and
the final approach are excluded). Each maximal slow interval counts once.

Planners that are free to choose which robot takes which final cell (the swarm has one
goal, not labelled ones) are compared on :func:`assignment_free_bound`: the same bound
minimized over every one-to-one assignment of the robots to the final cells.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from scipy.sparse import csr_array
from scipy.sparse.csgraph import dijkstra, maximum_bipartite_matching

if TYPE_CHECKING:
    from mrfswarm.trajectory import PiecewisePolynomial

#: Speed (m/s) under which a robot counts as stopped.
STOP_SPEED = 0.05
#: Sampling rate (Hz) of the stop count.
STOP_RATE_HZ = 50.0


def _graph(free: np.ndarray, resolution: float) -> csr_array:
    """The 8- (voxels: 26-) connected free-cell graph without corner cutting (the goal field's search graph of
    order d), edges in metres."""
    # imported here: the benchmarks load this file beside older revisions of the package, for the stop count
    from mrfswarm.discrete.goal_distance import free_moves, graph_moves

    order = free.ndim  # the whole 3^d - 1 neighbourhood
    src, dst, m = free_moves(free, order)
    length = np.sqrt((graph_moves(order, free.ndim)[m] ** 2).sum(axis=1)) * resolution
    n = free.size
    return csr_array((length, (_flat(src, free.shape), _flat(dst, free.shape))), shape=(n, n))


def _flat(cells: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    return np.ravel_multi_index(tuple(np.asarray(cells).T), shape)


def free_path_lengths(free: np.ndarray, starts: np.ndarray, ends: np.ndarray, resolution: float = 1.0,
                      via: np.ndarray | None = None) -> np.ndarray:
    """(N,) shortest free-path length (metres) from each ``starts[i]`` to ``ends[i]`` (cells).

    Cells are (N, d) on a grid ``free`` of d axes. With ``via`` (the free-path distance to
    one common cell over the grid, e.g. to the goal), only the robots that can hold the maximum are searched exactly: ``via[s] + via[e]`` bounds a
    robot's length from above (the way through that cell), so robots are searched in
    decreasing order of that bound until it falls below the longest exact length found;
    the others get NaN. Without ``via`` every robot is searched.
    """
    free = np.asarray(free, dtype=bool)
    starts, ends = np.asarray(starts, dtype=np.intp), np.asarray(ends, dtype=np.intp)
    graph = _graph(free, resolution)
    out = np.full(len(starts), np.nan)
    same = np.all(starts == ends, axis=1)
    out[same] = 0.0
    todo = np.flatnonzero(~same)
    if via is not None:
        upper = via[tuple(starts[todo].T)] + via[tuple(ends[todo].T)]
        todo = todo[np.argsort(-upper, kind="stable")]
        upper = np.sort(upper)[::-1]
    best = 0.0
    for n, i in enumerate(todo):
        if via is not None and upper[n] <= best:
            break
        d = dijkstra(graph, directed=True, indices=int(_flat(ends[i], free.shape)), limit=np.inf)
        out[i] = d[_flat(starts[i], free.shape)]
        best = max(best, float(out[i]))
    return out


def free_distances(free: np.ndarray, starts: np.ndarray, ends: np.ndarray, resolution: float = 1.0) -> np.ndarray:
    """(N, M) shortest free-path length (metres) from every ``starts[i]`` to every ``ends[j]`` (cells), on the
    graph of :func:`free_path_lengths`; ``inf`` where no path joins them."""
    free = np.asarray(free, dtype=bool)
    starts, ends = np.asarray(starts, dtype=np.intp), np.asarray(ends, dtype=np.intp)
    if len(starts) == 0 or len(ends) == 0:
        return np.zeros((len(starts), len(ends)))
    d = dijkstra(_graph(free, resolution), directed=True, indices=_flat(ends, free.shape), limit=np.inf)
    return np.asarray(d[:, _flat(starts, free.shape)].T)


def assignment_free_bound(free: np.ndarray, starts: np.ndarray, ends: np.ndarray, resolution: float,
                          v_max: float) -> float:
    """Seconds: :func:`makespan_lower_bound` minimized over every one-to-one assignment of the robots at ``starts``
    to the cells ``ends`` (as many cells as robots, or more): the smallest, over assignments, of the longest
    shortest free path, flown at ``v_max`` (the bottleneck assignment). No plan that brings the robots onto those
    cells, whichever robot takes which, ends sooner; ``inf`` when no assignment joins them all."""
    d = free_distances(free, starts, ends, resolution)
    n = len(d)
    if n == 0:
        return 0.0
    if d.shape[1] < n:
        raise ValueError(f"{n} robots and only {d.shape[1]} cells to end in")
    values = np.unique(d[np.isfinite(d)])
    lo, hi = 0, len(values) - 1  # the smallest threshold under which every robot can be matched
    if hi < 0 or not _all_matched(d <= values[hi]):
        return float("inf")
    while lo < hi:
        mid = (lo + hi) // 2
        if _all_matched(d <= values[mid]):
            hi = mid
        else:
            lo = mid + 1
    return float(values[lo]) / v_max


def _all_matched(allowed: np.ndarray) -> bool:
    """Whether the bipartite graph ``allowed`` (robots x cells) matches every robot."""
    match = maximum_bipartite_matching(csr_array(allowed.astype(np.int8)), perm_type="column")
    return bool(np.all(match >= 0))


def free_move_counts(free: np.ndarray, starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """(N,) fewest moves (MRF steps) from each ``starts[i]`` to ``ends[i]`` on the same free-cell graph as
    :func:`free_path_lengths` (a diagonal move counts one, as a straight one does); ``inf`` where no path
    joins them. No plan brings a robot there in fewer steps."""
    free = np.asarray(free, dtype=bool)
    starts, ends = np.asarray(starts, dtype=np.intp), np.asarray(ends, dtype=np.intp)
    graph = _graph(free, 1.0)
    graph.data[:] = 1.0
    out = np.zeros(len(starts))
    for i in np.flatnonzero(np.any(starts != ends, axis=1)):
        d = dijkstra(graph, directed=True, indices=int(_flat(ends[i], free.shape)), unweighted=True)
        out[i] = d[_flat(starts[i], free.shape)]
    return out


def makespan_lower_bound(free: np.ndarray, starts: np.ndarray, ends: np.ndarray, resolution: float, v_max: float,
                         via: np.ndarray | None = None) -> float:
    """Seconds: the longest shortest free path from a start cell to its final cell, at ``v_max``."""
    lengths = free_path_lengths(free, starts, ends, resolution, via)
    return float(np.nanmax(lengths, initial=0.0)) / v_max


@dataclass(frozen=True)
class Stops:
    """Stops inside each robot's flight and its mean speed.

    Attributes
    ----------
    per_robot
        (N,) number of stops of each robot.
    mean_speed
        (N,) path length over the flight's duration (m/s).
    """

    per_robot: np.ndarray
    mean_speed: np.ndarray

    @property
    def mean(self) -> float:
        return float(self.per_robot.mean()) if self.per_robot.size else 0.0


def stops_in_speeds(speeds: np.ndarray, speed: float = STOP_SPEED) -> np.ndarray:
    """Stops per robot (N,) in sampled speeds (S, N): slow intervals strictly inside each robot's flight.

    A robot's flight runs from the first sample at or above ``speed`` to the last; each maximal
    run of samples below ``speed`` between them counts once (see the module docstring).
    """
    v = np.asarray(speeds, dtype=float)
    fast = v >= speed
    S = len(v)
    first = np.argmax(fast, axis=0)
    last = S - 1 - np.argmax(fast[::-1], axis=0)
    rows = np.arange(S)[:, None]
    inside = (rows >= first) & (rows <= last) & ~fast  # slow samples within the flight
    entering = inside[1:] & ~inside[:-1]
    return np.where(fast.any(axis=0), entering.sum(axis=0), 0).astype(np.int64)


def count_stops(trajectories: list[PiecewisePolynomial], rate_hz: float = STOP_RATE_HZ,
                speed: float = STOP_SPEED) -> Stops:
    """Stops of every robot, sampled at ``rate_hz`` (see the module docstring)."""
    stops, means = [], []
    for tr in trajectories:
        t = np.linspace(0.0, tr.duration, max(2, int(np.ceil(tr.duration * rate_hz)) + 1))
        v = np.linalg.norm(tr.evaluate(t, 1), axis=-1)
        stops.append(int(stops_in_speeds(v[:, None], speed)[0]))
        dt = t[1] - t[0]
        means.append(float(v.sum() * dt / tr.duration) if tr.duration > 0 else 0.0)
    return Stops(np.asarray(stops, dtype=np.int64), np.asarray(means))
