"""A map drawn in coarser cells: ``scenario.map.coarsen = k``.

A robot must be smaller than half a cell (``scenario.robot_radius``), so a SLAM map of 0.05 m cells (ROS
``map_server``'s usual) took only robots of radius below 0.025 m (a map tour). ``coarsen = k`` draws any map in
cells of k of its own a side (k^d cells in a voxel map: voxels stay cubes), each as occupied as the most occupied of
its cells: one occupied or unknown cell makes the coarse cell an obstacle, so no obstacle of the map is lost and the
free space only shrinks. A block that reaches past the map's edge is padded with obstacles (off the map counts as a
wall). The coarse cell (0, ...) is the block of cells (0 .. k-1, ...): its centre, the map's ``origin``, is the
fine map's ``origin`` plus ``(k - 1) / 2`` fine cells on every axis; the resolution is k times the map's.

Coarsening comes after everything else the map's table says (``extrude`` too: an extruded map is coarsened on z as
well).
"""

from __future__ import annotations

import numpy as np

from mrfswarm.errors import ConfigError
from mrfswarm.maps.grid import OccupancyGrid
from mrfswarm.maps.spec import PREFIX

KEY = "coarsen"


def factor(value: object) -> int:
    """``scenario.map.coarsen``: an integer >= 1 (fine cells per coarse cell along each axis; 1 leaves the map)."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise ConfigError(f"{PREFIX}.{KEY} = {value!r}: must be an integer >= 1 (the map's cells per coarse cell "
                          "along each axis)")
    return int(value)


def coarsen(grid: OccupancyGrid, k: int) -> OccupancyGrid:
    """``grid`` in cells of ``k`` of its own a side, each P the largest of its cells (module docstring)."""
    if k == 1:
        return grid
    shape = np.array(grid.shape)
    blocks = -(-shape // k)
    padded = np.ones(tuple(blocks * k))  # past the map's edge: a wall
    padded[tuple(slice(0, n) for n in shape)] = grid.prob
    split = [v for n in blocks for v in (int(n), k)]
    prob = padded.reshape(split).max(axis=tuple(range(1, 2 * grid.ndim, 2)))
    origin = np.asarray(grid.origin) + 0.5 * (k - 1) * grid.resolution
    return OccupancyGrid(prob, resolution=grid.resolution * k, origin=tuple(float(v) for v in origin))
