"""Generated maps of the kinds people plan swarms on, each with a start and a goal.

Four classes, every map deterministic in its seed, 1 m cells at origin (0, 0) (the
MovingAI convention, so :func:`mrfswarm.maps.save_movingai` writes them unchanged):

``rooms``
    A grid of rooms behind 1-cell walls, joined by doorways 2 or 3 cells wide. The
    doorways follow a random spanning tree of the rooms (so the way from the start room
    to the goal room may wind through the others) plus one extra door. Start: the
    centre of a corner room; goal: the centre of the opposite one.
``trap``
    A U- or C-shaped wall (2 cells thick) whose open side faces the swarm, with the goal
    straight behind its base: the straight line to the goal ends in the cavity. The C
    closes part of the opening with inward lips. Turned to face any of four directions.
``forest``
    Single occupied cells scattered with density 10-20 %, away from small clearings
    around the start and the goal.
``maze``
    A perfect maze (a random spanning tree of a coarse grid) with corridors
    2 or 3 cells wide between 1-cell walls, and open halls (4 x 4 maze cells, 11-15 cells
    wide) at the start and the goal corners so that a swarm of 50 has room to start and
    to gather.

Every map keeps only the free region connected to the goal: free pockets cut off from it
(a forest can enclose some) are filled, so every free cell has a free path to the goal.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from mrfswarm.maps.grid import OccupancyGrid

#: 4-connectivity, the connectivity of robot moves (a diagonal needs both side cells free).
_CROSS = np.array([[0, 1, 0], [1, 1, 1], [0, 1, 0]], dtype=bool)


@dataclass(frozen=True)
class SyntheticMap:
    """A generated map with its start centre and goal (world metres = cells).

    Attributes
    ----------
    kind
        The class (a key of :data:`GENERATORS`).
    seed
        The seed it was generated from.
    occupied
        (W, H) bool.
    start
        Where the swarm starts (the centre of its start area).
    goal
        The goal cell.
    start_room
        Half-width (cells) of the free area around ``start``, to size the start sampling.
    variant
        What else distinguishes the map (the trap's shape, "U" or "C").
    """

    kind: str
    seed: int
    occupied: np.ndarray
    start: tuple[int, int]
    goal: tuple[int, int]
    start_room: int
    variant: str = ""

    @property
    def grid(self) -> OccupancyGrid:
        return OccupancyGrid.from_occupied(self.occupied)

    @property
    def name(self) -> str:
        return f"{self.kind}_{self.seed:02d}"


def _keep_goal_region(occ: np.ndarray, goal: tuple[int, int]) -> np.ndarray:
    """Fill every free cell that is not 4-connected to the goal."""
    labels, _ = ndimage.label(~occ, structure=_CROSS)
    return labels != labels[goal]


def _random_spanning_tree(nx_: int, ny_: int, rng: np.random.Generator) -> list[tuple[tuple[int, int], tuple[int, int]]]:
    """Edges of a random spanning tree of the nx_ x ny_ grid graph (randomized Kruskal).

    The minimum spanning tree (``scipy.sparse.csgraph``) under independent uniform edge
    weights: the classic randomized-Kruskal maze.
    """
    from scipy.sparse import coo_array
    from scipy.sparse.csgraph import minimum_spanning_tree

    idx = np.arange(nx_ * ny_).reshape(nx_, ny_)
    a = np.concatenate([idx[:-1, :].ravel(), idx[:, :-1].ravel()])
    b = np.concatenate([idx[1:, :].ravel(), idx[:, 1:].ravel()])
    w = rng.random(len(a)) + 1.0  # > 0: a zero weight would read as no edge
    tree = minimum_spanning_tree(coo_array((w, (a, b)), shape=(nx_ * ny_, nx_ * ny_))).tocoo()
    return [((int(i) // ny_, int(i) % ny_), (int(j) // ny_, int(j) % ny_)) for i, j in zip(tree.row, tree.col)]


def _border(W: int, H: int) -> np.ndarray:
    occ = np.zeros((W, H), dtype=bool)
    occ[[0, -1], :] = True
    occ[:, [0, -1]] = True
    return occ


def rooms(seed: int) -> SyntheticMap:
    """Rooms of 12-15 cells behind 1-cell walls, doorways 2-3 cells wide."""
    rng = np.random.default_rng(seed)
    nx_, ny_ = int(rng.integers(2, 4)), int(rng.integers(2, 4))
    if nx_ * ny_ < 4:
        ny_ = 2
    room = int(rng.integers(12, 16))
    step = room + 1
    W, H = nx_ * step + 1, ny_ * step + 1
    occ = np.zeros((W, H), dtype=bool)
    occ[::step, :] = True
    occ[:, ::step] = True
    doors = set(map(frozenset, _random_spanning_tree(nx_, ny_, rng)))
    grid_edges = [((i, j), (i + 1, j)) for i in range(nx_ - 1) for j in range(ny_)] + \
                 [((i, j), (i, j + 1)) for i in range(nx_) for j in range(ny_ - 1)]
    extra = [e for e in grid_edges if frozenset(e) not in doors]
    if extra:
        doors.add(frozenset(extra[int(rng.integers(len(extra)))]))
    for door in doors:
        (i0, j0), (i1, j1) = sorted(door)
        width = int(rng.integers(2, 4))
        lo = int(rng.integers(2, room - width - 1))
        if i0 != i1:  # rooms side by side in x: a door in the wall x = i1 * step
            x = i1 * step
            y = j0 * step + 1 + lo
            occ[x, y:y + width] = False
        else:
            y = j1 * step
            x = i0 * step + 1 + lo
            occ[x:x + width, y] = False
    centre = step // 2
    start = (centre, centre)
    goal = ((nx_ - 1) * step + centre, (ny_ - 1) * step + centre)
    return SyntheticMap("rooms", seed, _keep_goal_region(occ, goal), start, goal, room // 2)


def trap(seed: int) -> SyntheticMap:
    """A U or C wall facing the swarm, the goal behind its base."""
    rng = np.random.default_rng(seed)
    W, H = 56, 40
    occ = _border(W, H)
    t = 2
    inner = int(rng.integers(10, 17))  # cavity width (y)
    depth = int(rng.integers(8, 15))  # cavity depth (x)
    cy = H // 2 + int(rng.integers(-3, 4))
    base = 34 + int(rng.integers(-2, 3))  # x of the base's inner face
    y0, y1 = cy - inner // 2, cy - inner // 2 + inner  # cavity rows [y0, y1)
    occ[base:base + t, y0 - t:y1 + t] = True  # base
    occ[base - depth:base, y0 - t:y0] = True  # lower arm
    occ[base - depth:base, y1:y1 + t] = True  # upper arm
    shape = "U"
    if rng.random() < 0.5:  # C: lips close part of the opening
        lip = int(rng.integers(2, max(3, inner // 2 - 2)))
        occ[base - depth:base - depth + t, y0:y0 + lip] = True
        occ[base - depth:base - depth + t, y1 - lip:y1] = True
        shape = "C"
    start = (8, cy)
    goal = (min(W - 4, base + t + 10), cy)
    occ, start, goal = _turn(occ, start, goal, int(rng.integers(4)))
    return SyntheticMap("trap", seed, _keep_goal_region(occ, goal), start, goal, 6, shape)


def _turn(occ: np.ndarray, start: tuple[int, int], goal: tuple[int, int],
          quarter_turns: int) -> tuple[np.ndarray, tuple[int, int], tuple[int, int]]:
    """Rotate the map (and its points) by quarter turns, so the trap faces another way."""
    for _ in range(quarter_turns):
        H = occ.shape[1]
        occ = np.rot90(occ)  # (W, H) -> (H, W); cell (x, y) moves to (H - 1 - y, x)
        start = (H - 1 - start[1], start[0])
        goal = (H - 1 - goal[1], goal[0])
    return np.ascontiguousarray(occ), start, goal


def forest(seed: int) -> SyntheticMap:
    """Single occupied cells with density 10-20 %, clearings at the start and the goal."""
    rng = np.random.default_rng(seed)
    W, H = 48, 40
    density = float(rng.uniform(0.10, 0.18))  # cut-off pockets filled later add ~1 %
    occ = _border(W, H)
    occ[1:-1, 1:-1] = rng.random((W - 2, H - 2)) < density
    start = (6, int(rng.integers(8, H - 8)))
    goal = (W - 7, int(rng.integers(8, H - 8)))
    x, y = np.meshgrid(np.arange(W), np.arange(H), indexing="ij")
    for c, r in ((start, 4.5), (goal, 3.5)):
        occ[(x - c[0]) ** 2 + (y - c[1]) ** 2 <= r * r] = False
    return SyntheticMap("forest", seed, _keep_goal_region(occ, goal), start, goal, 4)


def maze(seed: int) -> SyntheticMap:
    """A perfect maze with 2-3-cell corridors and halls at the start and the goal."""
    rng = np.random.default_rng(seed)
    corridor = int(rng.integers(2, 4))
    n = int(rng.integers(10, 14)) if corridor == 2 else int(rng.integers(9, 12))
    step = corridor + 1
    W = H = n * step + 1
    occ = np.ones((W, H), dtype=bool)

    def block(i: int, j: int) -> tuple[slice, slice]:
        return slice(1 + i * step, 1 + i * step + corridor), slice(1 + j * step, 1 + j * step + corridor)

    for i in range(n):
        for j in range(n):
            occ[block(i, j)] = False
    for (i0, j0), (i1, j1) in _random_spanning_tree(n, n, rng):
        (i0, j0), (i1, j1) = sorted([(i0, j0), (i1, j1)])
        if i0 != i1:
            occ[1 + i0 * step + corridor, block(i0, j0)[1]] = False
        else:
            occ[block(i0, j0)[0], 1 + j0 * step + corridor] = False
    hall = 4 * step - 1  # 4 x 4 maze cells, inner walls removed
    occ[1:1 + hall, 1:1 + hall] = False
    occ[W - 1 - hall:W - 1, H - 1 - hall:H - 1] = False
    start = (1 + hall // 2, 1 + hall // 2)
    goal = (W - 2 - hall // 2, H - 2 - hall // 2)
    return SyntheticMap("maze", seed, _keep_goal_region(occ, goal), start, goal, hall // 2)


#: kind -> generator(seed); the one list of generated map classes.
GENERATORS: dict[str, Callable[[int], SyntheticMap]] = {
    "rooms": rooms,
    "trap": trap,
    "forest": forest,
    "maze": maze,
}


def generate(kind: str, seed: int) -> SyntheticMap:
    """The map of class ``kind`` for ``seed``.

    Raises
    ------
    KeyError
        Unknown class (the message lists the known ones).
    """
    if kind not in GENERATORS:
        raise KeyError(f"unknown map class {kind!r}; known: {', '.join(GENERATORS)}")
    return GENERATORS[kind](seed)
