"""Maps written in the config itself: ``free``, ``boxes`` and ``ascii``.

All three accept optional ``resolution`` (metres per cell, default 1.0) and ``origin``
(world coordinates of the centre of cell (0, 0), default [0, 0]) keys.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from mrfswarm.errors import ConfigError
from mrfswarm.maps import characters
from mrfswarm.maps.grid import MAX_CELLS, OccupancyGrid
from mrfswarm.maps.spec import PREFIX, check_keys, pair, placement, positive, size_cells

log = logging.getLogger(__name__)

_PLACEMENT = ("resolution", "origin")

#: ascii maps: '.' free; '#', '@' (and MovingAI's 'O', 'T') occupied; nothing else.
ASCII_FREE = "."
ASCII_OCCUPIED = "#@OT"
_ASCII_TABLE = characters.lookup_table(ASCII_FREE, ASCII_OCCUPIED)

# Boxes are half-open, [lo, hi) on each axis, like cells ([c - res/2, c + res/2)): a box of
# size L covers exactly L / res cells whatever its alignment (the blocks scenario's edges
# fall on cell centres, the corridor's on cell edges). A cell centre within this many
# metres (relative to the box's coordinates) of an edge counts as on it, so that such
# edges are not decided by floating-point rounding of res * i.
_BOX_TOL = 1e-9


def load_free(spec: dict, base_dir: Path) -> OccupancyGrid:
    """``{kind="free", size=[W, H]}``: W x H free cells."""
    check_keys(spec, ("kind", "size", *_PLACEMENT), PREFIX, required=("size",))
    w, h = size_cells(spec["size"], f"{PREFIX}.size")
    res, ox, oy = placement(spec)
    return OccupancyGrid(np.zeros((w, h)), resolution=res, origin=(ox, oy))


def load_boxes(spec: dict, base_dir: Path) -> OccupancyGrid:
    """``{kind="boxes", size=[W, H], boxes=[{center=[x, y], size=[lx, ly]}, ...]}``.

    A box (world metres) occupies every cell whose centre lies inside it, the box taken
    half-open like a cell: centre c is inside when ``center - size/2 <= c < center + size/2``
    on both axes, so a box of size L covers L / resolution cells. Boxes may extend past
    the map; the part outside is dropped.
    """
    check_keys(spec, ("kind", "size", "boxes", *_PLACEMENT), PREFIX, required=("size", "boxes"))
    w, h = size_cells(spec["size"], f"{PREFIX}.size")
    res, ox, oy = placement(spec)
    boxes = spec["boxes"]
    if not isinstance(boxes, (list, tuple)):
        raise ConfigError(f"{PREFIX}.boxes = {boxes!r}: must be a list of tables {{center=[x, y], size=[lx, ly]}}")
    xs = ox + res * np.arange(w)
    ys = oy + res * np.arange(h)
    occ = np.zeros((w, h), dtype=bool)
    for k, box in enumerate(boxes):
        where = f"{PREFIX}.boxes[{k}]"
        if not isinstance(box, dict):
            raise ConfigError(f"{where} = {box!r}: must be a table {{center=[x, y], size=[lx, ly]}}")
        check_keys(box, ("center", "size"), where, required=("center", "size"))
        cx, cy = pair(box["center"], f"{where}.center")
        size = box["size"]
        if not isinstance(size, (list, tuple)) or len(size) != 2:
            raise ConfigError(f"{where}.size = {size!r}: must be a list of 2 numbers [lx, ly] (metres)")
        lx, ly = positive(size[0], f"{where}.size[0]"), positive(size[1], f"{where}.size[1]")
        tol_x = _BOX_TOL * max(1.0, abs(cx), lx)
        tol_y = _BOX_TOL * max(1.0, abs(cy), ly)
        in_x = (xs >= cx - lx / 2 - tol_x) & (xs < cx + lx / 2 - tol_x)
        in_y = (ys >= cy - ly / 2 - tol_y) & (ys < cy + ly / 2 - tol_y)
        if not (in_x.any() and in_y.any()):
            log.warning("%s (center %s, size %s) contains no cell centre of the %d x %d map", where,
                        box["center"], box["size"], w, h)
        occ |= in_x[:, None] & in_y[None, :]
    return OccupancyGrid.from_occupied(occ, resolution=res, origin=(ox, oy))


def load_ascii(spec: dict, base_dir: Path) -> OccupancyGrid:
    """``{kind="ascii", rows=[...]}``: one string per row, row 0 first, column x = character x.

    '.' is free; '#', '@', 'O' and 'T' are occupied. The character at row y, column x
    is cell (x, y): no flip, so row 0 is y = 0 (the bottom of a plot with y up).
    """
    check_keys(spec, ("kind", "rows", *_PLACEMENT), PREFIX, required=("rows",))
    rows = spec["rows"]
    key = f"{PREFIX}.rows"
    if not isinstance(rows, (list, tuple)) or not rows:
        raise ConfigError(f"{key} = {rows!r}: must be a non-empty list of strings")
    for y, row in enumerate(rows):
        if not isinstance(row, str):
            raise ConfigError(f"{key}[{y}] = {row!r}: must be a string")
    width = len(rows[0])
    if width == 0:
        raise ConfigError(f"{key}[0] is empty: rows must have at least one character")
    for y, row in enumerate(rows):
        if len(row) != width:
            raise ConfigError(f"{key}[{y}] has {len(row)} characters, expected {width} (the length of {key}[0])")
    if width * len(rows) > MAX_CELLS:
        raise ConfigError(f"{key}: {width} x {len(rows)} cells exceeds the limit of {MAX_CELLS}")
    res, ox, oy = placement(spec)
    prob = characters.decode(list(rows), _ASCII_TABLE)
    if isinstance(prob, characters.BadCharacter):
        raise ConfigError(f"{key}[{prob.row}] column {prob.column}: unknown character {prob.char!r}; "
                          f"allowed: {ASCII_FREE!r} free, {', '.join(map(repr, ASCII_OCCUPIED))} occupied")
    return OccupancyGrid(prob, resolution=res, origin=(ox, oy))
