"""Checks of the ``scenario.map`` table's values, each raising a one-line :class:`ConfigError`.

Every message names the dotted key (``scenario.map.size``) and the bad value.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from mrfswarm.errors import ConfigError
from mrfswarm.maps.grid import MAX_CELLS

PREFIX = "scenario.map"


def check_keys(table: dict, allowed: tuple[str, ...], where: str, required: tuple[str, ...] = ()) -> None:
    """Unknown keys and missing required keys of ``table`` (found at ``where``)."""
    for key in table:
        if key not in allowed:
            raise ConfigError(f"unknown key {where}.{key}; allowed: {', '.join(allowed)}")
    for key in required:
        if key not in table:
            raise ConfigError(f"{where}.{key} is missing (required here; allowed keys: {', '.join(allowed)})")


def number(value: Any, key: str) -> float:
    """A finite real number (a bool is not one)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ConfigError(f"{key} = {value!r}: must be a finite number")
    return float(value)


def positive(value: Any, key: str) -> float:
    """A finite number > 0."""
    v = number(value, key)
    if v <= 0:
        raise ConfigError(f"{key} = {value!r}: must be > 0")
    return v


def pair(value: Any, key: str) -> tuple[float, float]:
    """Two finite numbers ``[x, y]``."""
    if not isinstance(value, (list, tuple)) or len(value) != 2:
        raise ConfigError(f"{key} = {value!r}: must be a list of 2 numbers [x, y]")
    return number(value[0], f"{key}[0]"), number(value[1], f"{key}[1]")


def size_cells(value: Any, key: str) -> tuple[int, int]:
    """A grid size ``[W, H]`` in cells: two integers >= 1 whose product is at most MAX_CELLS."""
    if not isinstance(value, (list, tuple)) or len(value) != 2:
        raise ConfigError(f"{key} = {value!r}: must be a list of 2 integers [W, H]")
    out = []
    for i, v in enumerate(value):
        if isinstance(v, bool) or not isinstance(v, int):
            raise ConfigError(f"{key}[{i}] = {v!r}: must be an integer (a number of cells)")
        if v < 1:
            raise ConfigError(f"{key}[{i}] = {v!r}: must be >= 1")
        out.append(v)
    if out[0] * out[1] > MAX_CELLS:
        raise ConfigError(f"{key} = {value!r}: {out[0] * out[1]} cells exceeds the limit of {MAX_CELLS}")
    return out[0], out[1]


def placement(spec: dict) -> tuple[float, float, float]:
    """The optional ``resolution`` (default 1.0) and ``origin`` (default [0, 0]) keys."""
    res = positive(spec.get("resolution", 1.0), f"{PREFIX}.resolution")
    ox, oy = pair(spec.get("origin", [0.0, 0.0]), f"{PREFIX}.origin")
    return res, ox, oy


def file_path(spec: dict, base_dir: Path | str) -> Path:
    """``spec["path"]`` resolved against ``base_dir`` (the config file's folder)."""
    value = spec["path"]
    if not isinstance(value, str) or not value:
        raise ConfigError(f"{PREFIX}.path = {value!r}: must be a non-empty string (a file path)")
    p = Path(value).expanduser()
    return p if p.is_absolute() else Path(base_dir) / p
