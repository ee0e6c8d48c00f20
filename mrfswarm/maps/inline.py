"""Maps written in the config itself: ``free``, ``boxes`` and ``ascii``.

All three accept optional ``resolution`` (metres per cell, default 1.0) and ``origin``
(world coordinates of the centre of cell (0, 0), default zeros, one number per axis) keys.
``free`` and ``boxes`` are 2-D or 3-D by the length of their ``size``; ``ascii`` is 2-D.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from mrfswarm.errors import ConfigError
from mrfswarm.maps import characters
from mrfswarm.maps.grid import MAX_CELLS, OccupancyGrid
from mrfswarm.maps.spec import PREFIX, check_keys, lengths, placement, point, size_cells

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
# edges are not decided by floating-point rounding of res * i; with ``fill = "overlap"``,
# a box face within it of a cell face touches that cell along the face only.
_BOX_TOL = 1e-9

#: ``fill`` of a boxes map: a box takes the cells whose centres it holds (the default), or
#: every cell it overlaps (with positive length on every axis).
FILLS = ("centres", "overlap")
#: A box (under ``fill = "centres"``) that reaches more than this many metres past the
#: cells it fills is a warning: robots may fly in the part of it the map does not hold.
REACH_TOL = 1e-3


def load_free(spec: dict, base_dir: Path) -> OccupancyGrid:
    """``{kind="free", size=[W, H]}`` or ``size=[W, H, D]``: W x H cells or W x H x D voxels, all free."""
    check_keys(spec, ("kind", "size", *_PLACEMENT), PREFIX, required=("size",))
    shape = size_cells(spec["size"], f"{PREFIX}.size")
    res, origin = placement(spec, len(shape))
    return OccupancyGrid(np.zeros(shape), resolution=res, origin=origin)


def load_boxes(spec: dict, base_dir: Path) -> OccupancyGrid:
    """``{kind="boxes", size=[W, H], boxes=[{center=[x, y], size=[lx, ly]}, ...]}``, or all of it with a z.

    A box (world metres) occupies every cell whose centre lies inside it, the box taken
    half-open like a cell: centre c is inside when ``center - size/2 <= c < center + size/2``
    on every axis, so a box of size L covers L / resolution cells. A box whose faces are
    not on cell faces then reaches past its cells (a 1.8 m cube centred on a 1 m voxel
    fills that voxel alone, and sticks out 0.4 m on every side): each such box, by more
    than :data:`REACH_TOL`, is a warning naming it and how far it reaches, unless the map gives
    ``fill = "centres"`` itself (the paper's blocks, whose faces are on cell centres). With
    ``fill = "overlap"`` a box occupies every cell it overlaps with positive length on
    every axis (the open box meets the open cell), so no point of it is in a free cell;
    a box whose faces are on cell faces fills the same cells under both rules. Boxes may
    extend past the map; the part outside is dropped (a box that overlaps no cell of the
    map is a warning). A map of ``size = [W, H, D]`` takes boxes of ``center = [x, y, z]``
    and ``size = [lx, ly, lz]``: the same rules, one axis more.
    """
    check_keys(spec, ("kind", "size", "boxes", "fill", *_PLACEMENT), PREFIX, required=("size", "boxes"))
    shape = size_cells(spec["size"], f"{PREFIX}.size")
    d = len(shape)
    res, origin = placement(spec, d)
    boxes = spec["boxes"]
    table = "{center=[x, y], size=[lx, ly]}" if d == 2 else "{center=[x, y, z], size=[lx, ly, lz]}"
    if not isinstance(boxes, (list, tuple)):
        raise ConfigError(f"{PREFIX}.boxes = {boxes!r}: must be a list of tables {table}")
    fill = spec.get("fill", FILLS[0])
    if not isinstance(fill, str) or fill not in FILLS:
        raise ConfigError(f"{PREFIX}.fill = {fill!r}: must be one of {', '.join(FILLS)}")
    centres = [o + res * np.arange(n) for o, n in zip(origin, shape)]  # cell centres along each axis
    where_map = " x ".join(map(str, shape))
    occ = np.zeros(shape, dtype=bool)
    for k, box in enumerate(boxes):
        where = f"{PREFIX}.boxes[{k}]"
        if not isinstance(box, dict):
            raise ConfigError(f"{where} = {box!r}: must be a table {table}")
        check_keys(box, ("center", "size"), where, required=("center", "size"))
        center = point(box["center"], f"{where}.center", d)
        size = lengths(box["size"], f"{where}.size", d)
        rows, touched, reach = [], True, 0.0
        for xs, c, length in zip(centres, center, size):
            tol = _BOX_TOL * max(1.0, abs(c), length)
            lo, hi = c - length / 2, c + length / 2
            touch = (xs + res / 2 > lo + tol) & (xs - res / 2 < hi - tol)  # the cells the open box meets
            held = (xs >= lo - tol) & (xs < hi - tol)  # the cells whose centres it holds
            rows.append(touch if fill == "overlap" else held)
            touched = touched and bool(touch.any())
            if rows[-1].any():  # how far the box, on the map, reaches past its cells' faces
                taken = xs[rows[-1]]
                lo, hi = max(lo, xs[0] - res / 2), min(hi, xs[-1] + res / 2)
                reach = max(reach, taken[0] - res / 2 - lo, hi - (taken[-1] + res / 2))
        if not touched:
            log.warning("%s (center %s, size %s) overlaps no cell of the %s map", where, box["center"], box["size"],
                        where_map)
        elif not all(m.any() for m in rows):
            log.warning("%s (center %s, size %s) holds no cell centre of the %s map, so it fills no cell and robots "
                        "may fly through it: align its faces with the cells' or set %s.fill = \"overlap\"", where,
                        box["center"], box["size"], where_map, PREFIX)
        elif reach > REACH_TOL and "fill" not in spec:  # fill = "centres" given: the rule is the user's choice
            log.warning("%s (center %s, size %s) reaches %.3g m past the cells it fills, where robots may fly: align "
                        "its faces with the cells' (at origin + resolution * (i +- 1/2)) or set %s.fill = \"overlap\"",
                        where, box["center"], box["size"], reach, PREFIX)
        occ[np.ix_(*rows)] = True  # the box's cells: the product of its rows along each axis
    return OccupancyGrid.from_occupied(occ, resolution=res, origin=origin)


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
    res, origin = placement(spec)
    prob = characters.decode(list(rows), _ASCII_TABLE)
    if isinstance(prob, characters.BadCharacter):
        raise ConfigError(f"{key}[{prob.row}] column {prob.column}: unknown character {prob.char!r}; "
                          f"allowed: {ASCII_FREE!r} free, {', '.join(map(repr, ASCII_OCCUPIED))} occupied")
    return OccupancyGrid(prob, resolution=res, origin=origin)
