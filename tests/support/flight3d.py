"""A 3-D flight built without the planner: a voxel map with a wall and a window, discrete paths through the
window, and their min-snap trajectories (the closed form, banded), for the tests of figures, flight and exports.

The discrete paths move at most one voxel per axis per step (26-neighbourhood moves) from the start block to
the goal block through the window; they are not a plan (no separation is claimed), only 3-D data of the shapes
a 3-D run produces: paths (T + 1, N, 3) on voxel centres, trajectories of 3 axes sharing their knots.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mrfswarm.maps import OccupancyGrid
from mrfswarm.trajectory import PiecewisePolynomial, solve_min_snap

#: The map: 32 x 16 x 8 voxels of 0.5 m, origin (0.25, 0.25, 0.25): a wall at x 7.75 .. 8.75 m with a window,
#: and a pillar after it.
SHAPE = (32, 16, 8)
RESOLUTION = 0.5
ORIGIN = (0.25, 0.25, 0.25)


@dataclass(frozen=True)
class Flight3D:
    grid: OccupancyGrid
    discrete: np.ndarray  # (T + 1, N, 3) metres, voxel centres
    trajectories: list[PiecewisePolynomial]  # N, 3 axes, shared knots (one piece per step)
    goal: np.ndarray  # (3,)
    step_s: float

    def positions(self, t: np.ndarray) -> np.ndarray:
        """(S, N, 3)."""
        return np.stack([tr.evaluate(np.clip(t, 0.0, tr.duration)) for tr in self.trajectories], axis=1)


def occupancy() -> np.ndarray:
    occ = np.zeros(SHAPE, dtype=bool)
    occ[15:17, :, :] = True  # the wall
    occ[15:17, 5:10, 2:6] = False  # the window: y cells 5..9, z cells 2..5
    occ[22:25, 2:5, :6] = True  # a pillar, short of the ceiling
    return occ


def _walk(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cells from a to b (inclusive) moving at most one cell per axis per step (the last point repeated)."""
    n = int(np.abs(b - a).max())
    s = np.linspace(0.0, 1.0, n + 1)[:, None]
    return np.rint(a + s * (b - a)).astype(int)


def window_flight(n_robots: int = 6, step_s: float = 0.6) -> Flight3D:
    """``n_robots`` (<= 12) robots from x cells 2..4 through the window to x cells 27..29."""
    grid = OccupancyGrid.from_occupied(occupancy(), RESOLUTION, ORIGIN)
    slots = [(y, z) for z in (2, 4, 5) for y in (5, 7, 9, 6)][:n_robots]
    cells = []
    for i, (y, z) in enumerate(slots):
        start = np.array([2 + i % 3, 2 + 2 * (i // 3), 1 + i % 2])
        legs = [start, np.array([13, y, z]), np.array([18, y, z]), np.array([28, 11 + (i % 4) - 2 * (i // 6), 6])]
        path = np.concatenate([_walk(p, q)[1:] if k else _walk(p, q) for k, (p, q) in enumerate(zip(legs, legs[1:]))])
        cells.append(path)
    T1 = max(len(c) for c in cells)
    cells = [np.concatenate([c, np.repeat(c[-1:], T1 - len(c), axis=0)]) for c in cells]
    paths = np.stack(cells, axis=1)  # (T + 1, N, 3)
    assert grid.is_free(paths).all()
    discrete = grid.cell_to_world(paths)
    durations = np.full(T1 - 1, step_s)
    trajectories = [solve_min_snap(discrete[:, i], durations).trajectory for i in range(len(slots))]
    return Flight3D(grid, discrete, trajectories, grid.cell_to_world(np.array([28, 10, 6])), step_s)
