"""experiments/bench/solo_reference.py: the fastest flight through a chain of boxes, against a closed form."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from support.repository import EXPERIMENTS

pytest.importorskip("casadi")
sys.path.insert(0, str(EXPERIMENTS / "bench"))
from solo_reference import fastest_flight, shortest_path  # noqa: E402

from mrfswarm.continuous.regions import build_regions  # noqa: E402
from mrfswarm.maps.grid import OccupancyGrid  # noqa: E402


def test_a_straight_run_takes_the_jerk_limited_rest_to_rest_time():
    """16 cells of 0.25 m along a free row, v 1, a 4, j 4: the speed limit is reached by jerk alone (a peak
    acceleration of 2 in 1 s, covering 0.5 m), so the run takes 1 + (4 - 1) / 1 + 1 = 5 s (3 m at cruise)."""
    grid = OccupancyGrid.from_occupied(np.zeros((20, 5), dtype=bool), resolution=0.25)
    path = shortest_path(grid.free, np.array([1, 2]), np.array([17, 2]), 0.25)
    assert len(path) == 17 and (path[:, 1] == 2).all()
    regions = build_regions(path[:, None, :], grid, 0.1, growth=20.0)
    total, durations = fastest_flight(grid.cell_to_world(path[0]), grid.cell_to_world(path[-1]), regions,
                                      1.0, 4.0, 4.0, knots=8)
    assert total == pytest.approx(5.0, abs=2e-3) and len(durations) == 16


def test_a_wall_across_the_way_costs_time():
    """The same run with a wall and a door off the straight line: longer than the straight run."""
    occ = np.zeros((20, 9), dtype=bool)
    occ[9, :] = True
    occ[9, 7] = False  # the door, 5 cells off the row y = 2
    grid = OccupancyGrid.from_occupied(occ, resolution=0.25)
    path = shortest_path(grid.free, np.array([1, 2]), np.array([17, 2]), 0.25)
    assert any(tuple(c) == (9, 7) for c in path)
    regions = build_regions(path[:, None, :], grid, 0.1, growth=20.0)
    total, _ = fastest_flight(grid.cell_to_world(path[0]), grid.cell_to_world(path[-1]), regions, 1.0, 4.0, 4.0,
                              knots=6)
    assert total > 5.2
