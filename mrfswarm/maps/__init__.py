"""Occupancy grids, every map format, and world <-> cell conversion in one place.

:class:`OccupancyGrid` holds P(occupied) per cell, indexed ``[ix, iy]``, with its
resolution and the world position of the centre of cell (0, 0); it converts between
world and cell coordinates (nothing else in mrfswarm does). :func:`load_map` builds a
grid from the config table ``scenario.map``; one loader per ``kind``:

============  =================================================================
``free``      ``{kind="free", size=[W, H]}``
``boxes``     ``{kind="boxes", size=[W, H], boxes=[{center=[x, y], size=[lx, ly]}, ...]}``
``ascii``     ``{kind="ascii", rows=["..#.", ...]}``
``movingai``  ``{kind="movingai", path="map.map"}`` (MovingAI benchmark ``.map``)
``ros``       ``{kind="ros", path="map.yaml"}`` (ROS map_server YAML + PGM/PNG)
============  =================================================================

``free``, ``boxes``, ``ascii`` and ``movingai`` also take ``resolution`` (metres per cell,
default 1.0) and ``origin`` (the centre of cell (0, 0), default [0, 0]); a ROS map's come
from its YAML, which the config's may state but not change. Writers:
:func:`save_movingai`, :func:`save_ros`.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from mrfswarm.errors import ConfigError
from mrfswarm.maps.grid import OCCUPIED_THRESHOLD, OccupancyGrid
from mrfswarm.maps.inline import load_ascii, load_boxes, load_free
from mrfswarm.maps.movingai import load_movingai, read_movingai, save_movingai
from mrfswarm.maps.ros import load_ros, read_ros, save_ros
from mrfswarm.maps.spec import PREFIX

#: kind -> loader(spec, base_dir); the one list of map kinds.
LOADERS: dict[str, Callable[[dict, Path], OccupancyGrid]] = {
    "free": load_free,
    "boxes": load_boxes,
    "ascii": load_ascii,
    "movingai": load_movingai,
    "ros": load_ros,
}


def load_map(spec: dict, base_dir: Path | str = ".") -> OccupancyGrid:
    """Build the occupancy grid described by the config table ``scenario.map``.

    Parameters
    ----------
    spec
        The table, e.g. ``{"kind": "boxes", "size": [40, 40], "boxes": [...]}``.
    base_dir
        Folder that relative ``path`` values are resolved against (the config file's).

    Raises
    ------
    ConfigError
        Bad table: unknown kind or key, missing key, wrong type, size < 1, resolution
        <= 0, malformed ascii rows. Names the key and the bad value.
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
    return LOADERS[kind](spec, Path(base_dir))


__all__ = [
    "LOADERS",
    "OCCUPIED_THRESHOLD",
    "OccupancyGrid",
    "load_map",
    "read_movingai",
    "read_ros",
    "save_movingai",
    "save_ros",
]
