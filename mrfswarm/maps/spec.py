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


#: How a point of each length is written in messages.
AXES = {2: "[x, y]", 3: "[x, y, z]"}


def point(value: Any, key: str, d: int) -> tuple[float, ...]:
    """``d`` finite numbers, ``[x, y]`` or ``[x, y, z]`` (metres)."""
    if not isinstance(value, (list, tuple)) or len(value) != d:
        raise ConfigError(f"{key} = {value!r}: must be a list of {d} numbers {AXES[d]}{on_map(d)}")
    return tuple(number(v, f"{key}[{i}]") for i, v in enumerate(value))


def lengths(value: Any, key: str, d: int) -> tuple[float, ...]:
    """``d`` finite numbers > 0, ``[lx, ly]`` or ``[lx, ly, lz]`` (metres)."""
    if not isinstance(value, (list, tuple)) or len(value) != d:
        shown = "[lx, ly]" if d == 2 else "[lx, ly, lz]"
        raise ConfigError(f"{key} = {value!r}: must be a list of {d} numbers {shown} (metres){on_map(d)}")
    return tuple(positive(v, f"{key}[{i}]") for i, v in enumerate(value))


def on_map(d: int) -> str:
    """What a message adds about the map's dimension (nothing on a 2-D map, whose messages are as they were)."""
    return " on a 3-D map" if d == 3 else ""


def size_cells(value: Any, key: str) -> tuple[int, ...]:
    """A grid size ``[W, H]`` or ``[W, H, D]`` in cells: integers >= 1 whose product is at most MAX_CELLS."""
    if not isinstance(value, (list, tuple)) or len(value) not in (2, 3):
        raise ConfigError(f"{key} = {value!r}: must be a list of 2 integers [W, H] or 3 [W, H, D]")
    out = []
    for i, v in enumerate(value):
        if isinstance(v, bool) or not isinstance(v, int):
            raise ConfigError(f"{key}[{i}] = {v!r}: must be an integer (a number of cells)")
        if v < 1:
            raise ConfigError(f"{key}[{i}] = {v!r}: must be >= 1")
        out.append(v)
    if math.prod(out) > MAX_CELLS:
        raise ConfigError(f"{key} = {value!r}: {math.prod(out)} cells exceeds the limit of {MAX_CELLS}")
    return tuple(out)


def placement(spec: dict, d: int = 2) -> tuple[float, tuple[float, ...]]:
    """The optional ``resolution`` (default 1.0) and ``origin`` (default zeros, ``d`` numbers) keys."""
    res = positive(spec.get("resolution", 1.0), f"{PREFIX}.resolution")
    origin = point(spec.get("origin", [0.0] * d), f"{PREFIX}.origin", d)
    return res, origin


def file_path(spec: dict, base_dir: Path | str) -> Path:
    """``spec["path"]`` resolved against ``base_dir`` (the config file's folder)."""
    value = spec["path"]
    if not isinstance(value, str) or not value:
        raise ConfigError(f"{PREFIX}.path = {value!r}: must be a non-empty string (a file path)")
    p = Path(value).expanduser()
    return p if p.is_absolute() else Path(base_dir) / p
