"""A 2-D map of any kind raised into a voxel map: ``scenario.map.extrude = D``.

Every cell of the plan becomes a column of ``D`` voxels of the same occupancy (walls reach
the ceiling), with the map's resolution on z too (voxels are cubes). The map's box is the
room: off the map counts as occupied everywhere in the planner
(:class:`~mrfswarm.maps.obstacles.ObstacleIndex`, :meth:`OccupancyGrid.is_free`), so the
floor below layer 0 and the ceiling above layer D - 1 are walls without voxels of their own.

``origin`` then has three numbers, the centre of voxel (0, 0, 0): z of layer k's centre
is ``origin[2] + resolution * k`` (default 0: layer 0 centred at z = 0, its floor at
``-resolution / 2``; give ``origin[2] = resolution / 2`` to put the floor at z = 0). The
2-D map's own loader sees ``origin[:2]`` (so a ROS map's x and y must still agree with its
YAML).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

from mrfswarm.errors import ConfigError
from mrfswarm.maps.grid import MAX_CELLS, OccupancyGrid
from mrfswarm.maps.spec import PREFIX, point

KEY = "extrude"


def depth(value: object) -> int:
    """``scenario.map.extrude``: an integer >= 1 (voxels along z)."""
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise ConfigError(f"{PREFIX}.{KEY} = {value!r}: must be an integer >= 1 (the height in voxels)")
    return value


def extrude(grid: OccupancyGrid, layers: int, z0: float = 0.0) -> OccupancyGrid:
    """The 2-D ``grid`` repeated over ``layers`` voxels along z, layer 0 centred at ``z0``.

    Raises
    ------
    ConfigError
        ``grid`` is already 3-D, or the voxel map would exceed the cell limit.
    """
    if grid.ndim != 2:
        raise ConfigError(f"{PREFIX}.{KEY} = {layers!r}: the map is already 3-D ({' x '.join(map(str, grid.shape))} "
                          f"voxels); {KEY} raises a 2-D map")
    if grid.prob.size * layers > MAX_CELLS:
        raise ConfigError(f"{PREFIX}.{KEY} = {layers!r}: {grid.width} x {grid.height} x {layers} voxels exceeds the "
                          f"limit of {MAX_CELLS}")
    prob = np.broadcast_to(grid.prob[:, :, None], (*grid.shape, layers))
    return OccupancyGrid(prob, resolution=grid.resolution, origin=(*grid.origin, z0))


def load_extruded(spec: dict, base_dir: Path, loader: Callable[[dict, Path], OccupancyGrid]) -> OccupancyGrid:
    """The map of ``spec`` without its ``extrude`` key, loaded by ``loader`` and extruded (module docstring)."""
    layers = depth(spec[KEY])
    size = spec.get("size")
    if isinstance(size, (list, tuple)) and len(size) == 3:
        raise ConfigError(f"{PREFIX}.{KEY} = {layers!r}: the map is already 3-D (size = {size!r}); {KEY} raises a "
                          f"2-D map")
    flat = {k: v for k, v in spec.items() if k != KEY}
    z0 = 0.0
    if "origin" in spec:
        try:
            x, y, z0 = point(spec["origin"], f"{PREFIX}.origin", 3)
        except ConfigError as e:  # a 2-number origin read as a 3-D tour's puzzle: say what made the map 3-D
            raise ConfigError(f"{e} ({PREFIX}.{KEY} makes it one: its z is the centre of layer 0)") from None
        flat["origin"] = [x, y]
    return extrude(loader(flat, base_dir), layers, z0)
