"""Occupancy grids, every map format, and world <-> cell conversion in one place.

:class:`OccupancyGrid` holds P(occupied) per cell, indexed ``[ix, iy]``, with its
resolution and the world position of the centre of cell (0, 0); it converts between
world and cell coordinates (nothing else in mrfswarm does). :func:`load_map` builds a
grid from the config table ``scenario.map``; one loader per ``kind``:

============  =================================================================
``free``      ``{kind="free", size=[W, H]}`` or ``size=[W, H, D]`` (voxels)
``boxes``     ``{kind="boxes", size=[W, H], boxes=[{center=[x, y], size=[lx, ly]}, ...]}``;
              with ``size=[W, H, D]``, boxes of ``center=[x, y, z]``, ``size=[lx, ly, lz]``
              (a box takes the cells whose centres it holds; ``fill="overlap"``: every cell it overlaps)
``ascii``     ``{kind="ascii", rows=["..#.", ...]}``
``movingai``  ``{kind="movingai", path="map.map"}`` (MovingAI benchmark ``.map``)
``ros``       ``{kind="ros", path="map.yaml"}`` (ROS map_server YAML + PGM/PNG)
``npy``       ``{kind="npy", path="map.npy"}`` (a (W, H, D) or (W, H) NumPy array, True occupied)
``binvox``    ``{kind="binvox", path="map.binvox"}`` (binvox voxels, read with trimesh)
============  =================================================================

All but ``ros`` also take ``resolution`` (metres per cell, default 1.0) and ``origin``
(the centre of cell (0, 0[, 0]), default zeros, one number per axis of the map); a ROS
map's come from its YAML, which the config's may state but not change. A 2-D map of any
kind takes ``extrude = D``: its cells raised into columns of D voxels
(:mod:`mrfswarm.maps.extrusion`). Any map takes ``coarsen = k``: drawn in cells of k of its own a side, each as
occupied as its most occupied cell (:mod:`mrfswarm.maps.coarsening`; a 0.05 m SLAM map for robots of 0.1 m). Writers: :func:`save_movingai`, :func:`save_ros`,
:func:`save_voxels`.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from mrfswarm.errors import ConfigError
from mrfswarm.maps import coarsening, extrusion
from mrfswarm.maps.grid import OCCUPIED_THRESHOLD, OccupancyGrid
from mrfswarm.maps.inline import load_ascii, load_boxes, load_free
from mrfswarm.maps.movingai import load_movingai, read_movingai, save_movingai
from mrfswarm.maps.ros import load_ros, read_ros, save_ros
from mrfswarm.maps.spec import PREFIX
from mrfswarm.maps.voxels import load_binvox, load_npy, read_binvox, read_npy, save_voxels

#: kind -> loader(spec, base_dir); the one list of map kinds.
LOADERS: dict[str, Callable[[dict, Path], OccupancyGrid]] = {
    "free": load_free,
    "boxes": load_boxes,
    "ascii": load_ascii,
    "movingai": load_movingai,
    "ros": load_ros,
    "npy": load_npy,
    "binvox": load_binvox,
}
#: The kinds that take ``extrude`` (2-D maps; ``free`` and ``boxes`` when their size has 2 numbers). A 2-D ``npy``
#: array takes it too, in its loader: whether the array is 2-D is known once the file is read.
EXTRUDABLE = ("free", "boxes", "ascii", "movingai", "ros")


def load_map(spec: dict, base_dir: Path | str = ".") -> OccupancyGrid:
    """Build the occupancy grid described by the config table ``scenario.map``.

    Parameters
    ----------
    spec
        The table, e.g. ``{"kind": "boxes", "size": [40, 40], "boxes": [...]}``, with
        ``extrude`` for a 2-D map raised to that many voxels.
    base_dir
        Folder that relative ``path`` values are resolved against (the config file's).

    Raises
    ------
    ConfigError
        Bad table: unknown kind or key, missing key, wrong type, size < 1, resolution
        <= 0, malformed ascii rows, a point or size with the wrong number of axes for the
        map. Names the key and the bad value.
    ScenarioError
        A missing or malformed map file. Names the file and what is wrong.
    """
    if not isinstance(spec, dict):
        raise ConfigError(f"{PREFIX} = {spec!r}: must be a table with a 'kind' key")
    if "kind" not in spec:
        raise ConfigError(f"{PREFIX}.kind is missing; one of {', '.join(LOADERS)}")
    kind = spec["kind"]
    if not isinstance(kind, str) or kind not in LOADERS:
        raise ConfigError(f"{PREFIX}.kind = {kind!r}: must be one of {', '.join(LOADERS)}")
    if coarsening.KEY in spec:  # last of all: the map as its table draws it, then in coarser cells
        k = coarsening.factor(spec[coarsening.KEY])
        return coarsening.coarsen(load_map({key: v for key, v in spec.items() if key != coarsening.KEY}, base_dir), k)
    if extrusion.KEY in spec and kind in EXTRUDABLE:  # the voxel kinds' own key check refuses it
        return extrusion.load_extruded(spec, Path(base_dir), LOADERS[kind])
    return LOADERS[kind](spec, Path(base_dir))


__all__ = [
    "EXTRUDABLE",
    "LOADERS",
    "OCCUPIED_THRESHOLD",
    "OccupancyGrid",
    "load_map",
    "read_binvox",
    "read_movingai",
    "read_npy",
    "read_ros",
    "save_movingai",
    "save_ros",
    "save_voxels",
]
