"""Distances to the goal over free paths (geodesic), computed once per scenario.

The paper's goal potential rho_G(p) = a_G exp(|p - p_g| / k_G) uses the straight-line
distance, so every concave obstacle between the swarm and its goal is a local minimum
where ICM, a local method, stops. Here the distance is measured along free paths: a
shortest-path search (``scipy.sparse.csgraph.dijkstra``) from the goal over a graph whose
vertices are the free cells and whose edges are the moves a robot can make in one MRF
step: the 8 neighbours for search order n >= 2 (4 for n = 1), a diagonal move only when
both cells beside it are free (the motion rule of :mod:`mrfswarm.discrete.motion`). On voxels
(d = 3) the same rule, one axis more: the moves of the order min(n, 3) stencil, 6, 18 or
26 neighbours (all of them labels of order n), a face-diagonal move only when the two
voxels beside the edge it passes are free, a space-diagonal one when the whole 2 x 2 x 2
block is (no edge or corner cut). Two distances come out of it:

- :attr:`GoalDistance.path`: the length (metres) of the shortest free path, with 8
  (or 4) move directions, so it exceeds the true Euclidean path length by up to 8.2 %
  (4-connected: 41 %) in directions between the grid's. It says how far a robot is
  from the goal, whether it can get there at all (``inf`` if not) and which cells form
  the goal region.
- :attr:`GoalDistance.field`: the distance the goal potential uses. A move from p to q
  costs its length plus the rise of the obstacle potential along it in units of goal
  distance, ``|q - p| + (k_G / a_G) max(0, rho_O(q) - rho_O(p))``. Without the second
  term the combined static field rho_S = rho_G + rho_O can still have local minima in
  front of doorways: the blurred walls on both sides raise rho_O inside a 2-3-cell
  doorway by up to ~1.2 (Gamma 5, sigma 1), while near the goal one metre lowers rho_G
  by only a_G / k_G = 0.15. With it, rho_S has none (proof below). Where rho_O is flat
  (more than ~3 sigma_hat from walls) the two distances agree.

Guarantee (by construction; checked on random maps in the tests). Let D be the field
distance and q the next cell on p's shortest path (Dijkstra's predecessor), reached by
a move of length L. Then D(p) = D(q) + L + (k_G / a_G) max(0, rho_O(q) - rho_O(p)), and
with rho_G = a_G exp(D / k_G) >= a_G and exp(x) - 1 >= x,

    rho_G(p) - rho_G(q) = a_G exp(D(q) / k_G) (exp((D(p) - D(q)) / k_G) - 1)
                        >= (a_G / k_G) (D(p) - D(q))
                        >= (a_G / k_G) L + rho_O(q) - rho_O(p),

so rho_S(p) - rho_S(q) >= (a_G / k_G) L > 0: from every free cell connected to the goal,
except the goal, one move (a label of every search order n >= 1) lowers the static field
by at least a_G / k_G per metre. The goal is its only local minimum. This is a property of
the static field: the robots' interaction (Morse) and the one-robot-per-cell rule can
still hold a robot back; :mod:`mrfswarm.discrete.robot_outcomes` reports it when they do.

Free cells not connected to the goal have ``inf`` distances (and an ``inf`` static
field): a robot there has no path to the goal, which the scenario rejects with an error
naming the robot. Occupied cells are ``inf`` too.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.sparse import csr_array
from scipy.sparse.csgraph import dijkstra

from mrfswarm.discrete.motion import cell_values, moves_clear, stencil
from mrfswarm.geometry import norm

#: Label-set order whose moves form the search graph for orders >= d (all 3^d - 1 neighbours).
_GRAPH_ORDER = {2: 2, 3: 3}


@dataclass(frozen=True)
class GoalDistance:
    """Distances from every cell to the goal over free paths, (W, H) or (W, H, D) each, metres.

    Attributes
    ----------
    path
        Length of the shortest free path; ``inf`` for occupied cells and free cells not
        connected to the goal.
    field
        The distance the goal potential uses: ``path`` plus the obstacle potential climbed
        on the way, in units of goal distance (equal to ``path`` when no climb weight is
        given); ``inf`` where ``path`` is.
    next_cell
        (W, H, 2) or (W, H, D, 3) the next cell on each cell's ``field``-shortest path (itself for the goal,
        -1 where unreachable): the move that lowers the static field.
    graph
        The search graph ``field`` was searched on (:class:`GoalGraph`, its climb weighted as given), kept for the
        congestion's searches (:mod:`mrfswarm.discrete.congestion`), which built it again: 5.6 s on a 2000 x 2000
        map (a map tour); None where not kept.
    """

    path: np.ndarray
    field: np.ndarray
    next_cell: np.ndarray
    graph: GoalGraph | None = None

    @property
    def reachable(self) -> np.ndarray:
        """The grid's shape, bool: free cells with a free path to the goal (the goal included)."""
        return np.isfinite(self.path)


def graph_order(order: int, ndim: int = 2) -> int:
    """The stencil order of the search graph: min(n, d) (the whole 3^d block from n = d on)."""
    return min(order, _GRAPH_ORDER[ndim])


def graph_moves(order: int, ndim: int = 2) -> np.ndarray:
    """The moves (S, d) that are edges of the search graph for label-set order ``order``.

    In the plane the 4 neighbours for n = 1, the 8 neighbours for n >= 2; on voxels 6,
    18 or 26 for n = 1, 2, >= 3. Every one is a label of that order, so the next cell
    toward the goal is always one move away.
    """
    off = stencil(graph_order(order, ndim), ndim)
    return off[1:]  # without "stay"


def free_moves(free: np.ndarray, order: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Directed edges (from p, to q, move index) of the clear one-step moves between free cells (d = ``free.ndim``)."""
    cells = np.argwhere(free)
    moves = graph_moves(order, free.ndim)
    S = len(moves) + 1  # moves_clear takes stencil indices; index 0 is "stay"
    ok = moves_clear(free, cells, np.broadcast_to(np.arange(1, S), (len(cells), S - 1)), graph_order(order, free.ndim))
    p_idx, m_idx = np.nonzero(ok)
    src = cells[p_idx]
    dst = src + moves[m_idx]
    return src, dst, m_idx


def goal_distance(free: np.ndarray, goal_cell: np.ndarray, resolution: float = 1.0, order: int = 2,
                  obstacle: np.ndarray | None = None, climb_weight: float = 0.0) -> GoalDistance:
    """Shortest free-path distances from every cell to ``goal_cell`` (one Dijkstra search each).

    Parameters
    ----------
    free
        (W, H) or (W, H, D) bool, True where free.
    goal_cell
        (d,) a free cell, integer indices.
    resolution
        Metres per cell.
    order
        The label-set order n (n = 1: 4-connected search graph, n >= 2: 8-connected; on
        voxels 6-, 18-, 26-connected for n = 1, 2, >= 3).
    obstacle
        The obstacle potential over the grid rho_O, needed when ``climb_weight > 0``.
    climb_weight
        Metres of goal distance per unit of obstacle potential climbed (k_G / a_G makes
        rho_G + rho_O free of local minima; 0 gives ``field == path``).

    Returns
    -------
    GoalDistance
    """
    graph = GoalGraph.build(free, goal_cell, resolution, order, obstacle, climb_weight)
    path, nxt = graph.search(graph.length)
    field = path
    if climb_weight > 0:
        field, nxt = graph.search(graph.length + graph.climb)
    return GoalDistance(path=path, field=field, next_cell=nxt, graph=graph)


@dataclass(frozen=True)
class GoalGraph:
    """The search graph of :func:`goal_distance`, kept for searches with other move costs.

    Edges point from q (nearer the goal) to p, so that one search from the goal follows
    them: the cost of the move p -> q sits on the edge q -> p.

    Attributes
    ----------
    shape
        The grid's shape.
    tail, head
        (E,) flat indices of each edge's ends (q, p).
    into
        (E, d) the cell each move enters (q).
    length
        (E,) each move's length (metres).
    climb
        (E,) the obstacle potential each move climbs, times the climb weight (metres; zeros without one).
    goal
        The goal cell's flat index.
    """

    shape: tuple[int, ...]
    tail: np.ndarray
    head: np.ndarray
    into: np.ndarray
    length: np.ndarray
    climb: np.ndarray
    goal: int

    @classmethod
    def build(cls, free: np.ndarray, goal_cell: np.ndarray, resolution: float = 1.0, order: int = 2,
              obstacle: np.ndarray | None = None, climb_weight: float = 0.0) -> GoalGraph:
        """The graph of the clear moves between free cells (arguments of :func:`goal_distance`)."""
        free = np.asarray(free, dtype=bool)
        shape = free.shape
        raw = np.asarray(goal_cell)
        if raw.dtype.kind not in "iu":  # 2.5 was read as cell 2 without a word (a library tour)
            raise TypeError(f"goal cell {raw.tolist()!r} must be integer cell indices, got dtype {raw.dtype}")
        g = raw.astype(np.intp)
        if not (g.shape == (free.ndim,) and np.all((g >= 0) & (g < shape)) and free[tuple(g)]):
            raise ValueError(f"goal cell {tuple(int(v) for v in g)} is not a free cell of the "
                             f"{' x '.join(str(n) for n in shape)} grid")
        if climb_weight < 0 or not math.isfinite(climb_weight):
            raise ValueError(f"climb_weight must be finite and >= 0, got {climb_weight!r}")
        if climb_weight > 0 and obstacle is None:
            raise ValueError("climb_weight > 0 needs the obstacle potential")
        src, dst, m_idx = free_moves(free, order)
        length = norm(graph_moves(order, free.ndim)[m_idx]) * resolution
        climb = np.zeros_like(length)
        if climb_weight > 0 and obstacle is not None:
            climb = climb_weight * np.maximum(0.0, cell_values(obstacle, dst) - cell_values(obstacle, src))
        return cls(shape=shape, tail=np.ravel_multi_index(tuple(dst.T), shape),
                   head=np.ravel_multi_index(tuple(src.T), shape), into=dst, length=length, climb=climb,
                   goal=int(np.ravel_multi_index(tuple(g), shape)))

    def search(self, cost: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Distances to the goal (the grid's shape, metres) with ``cost`` (E,) per move, and each cell's next
        cell on its shortest path (shape + (d,); the goal itself for the goal, -1 where unreachable)."""
        n = int(np.prod(self.shape))
        dist, pred = _search(self.tail, self.head, cost, n, self.goal)
        nxt = np.full((n, len(self.shape)), -1, dtype=np.intp)
        has = pred >= 0
        nxt[has] = np.stack(np.unravel_index(pred[has], self.shape), axis=1)
        nxt[self.goal] = np.unravel_index(self.goal, self.shape)
        return dist.reshape(self.shape), nxt.reshape(*self.shape, len(self.shape))


def _search(a: np.ndarray, b: np.ndarray, cost: np.ndarray, n: int, source: int) -> tuple[np.ndarray, np.ndarray]:
    """Dijkstra from ``source`` over directed edges a -> b; distances and predecessors (n,)."""
    graph = csr_array((cost, (a, b)), shape=(n, n))
    dist, pred = dijkstra(graph, directed=True, indices=source, return_predecessors=True)
    return dist, pred
