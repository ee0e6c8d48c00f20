"""MovingAI benchmark maps (``.map``), read and written.

Format (Sturtevant, "Benchmarks for Grid-Based Pathfinding", IEEE TCIAIG 2012;
https://movingai.com/benchmarks/formats.html)::

    type octile
    height H
    width W
    map
    <H lines of W characters>

Terrain: '.' and 'G' passable, 'S' swamp (passable), 'W' water, '@' and 'O' out of
bounds, 'T' trees. Column x and row y as in the file, row 0 the first map line, no flip.
The format has no scale: cells are 1 m with cell (0, 0) centred at (0, 0) unless the config
gives ``resolution`` (metres per cell) and ``origin`` (the centre of cell (0, 0)), as for
``free``, ``boxes`` and ``ascii`` maps.

Decision for aerial robots: WATER ('W') IS FREE. On the benchmarks it only stops ground
agents; a swarm flying at a fixed altitude crosses it like swamp. Trees ('T') stay
obstacles (they reach flight altitude). So: free '.', 'G', 'S', 'W'; occupied '@', 'O', 'T'.
"""

from __future__ import annotations

import codecs
import logging
from pathlib import Path

from mrfswarm.errors import ScenarioError
from mrfswarm.file_input import read_bytes
from mrfswarm.maps import characters
from mrfswarm.maps.grid import MAX_CELLS, OccupancyGrid
from mrfswarm.maps.spec import PREFIX, check_keys, file_path, placement

log = logging.getLogger(__name__)

FREE = ".GSW"
OCCUPIED = "@OT"
_TABLE = characters.lookup_table(FREE, OCCUPIED)


def load_movingai(spec: dict, base_dir: Path) -> OccupancyGrid:
    """``{kind="movingai", path=..., resolution=R, origin=[x, y]}``: a MovingAI ``.map`` file.

    ``path`` is relative to ``base_dir``; ``resolution`` (default 1.0 m) and ``origin``
    (default [0, 0]) place the cells, which the file does not.
    """
    check_keys(spec, ("kind", "path", "resolution", "origin"), PREFIX, required=("path",))
    res, origin = placement(spec)
    return read_movingai(file_path(spec, base_dir), resolution=res, origin=(origin[0], origin[1]))


def _header_int(lines: list[str], n: int, name: str, path: Path) -> int:
    parts = lines[n].split()
    if len(parts) != 2 or parts[0] != name:
        raise ScenarioError(f"{path}: line {n + 1}: expected '{name} <integer>', got {lines[n]!r}")
    try:
        v = int(parts[1])
    except ValueError:
        raise ScenarioError(f"{path}: line {n + 1}: {name} {parts[1]!r} is not an integer") from None
    if v < 1:
        raise ScenarioError(f"{path}: line {n + 1}: {name} {v} must be >= 1")
    return v


def read_movingai(path: Path | str, resolution: float = 1.0,
                  origin: tuple[float, float] = (0.0, 0.0)) -> OccupancyGrid:
    """Read a MovingAI ``.map`` file into a grid of ``resolution`` m cells, cell (0, 0) centred at ``origin``.

    The header's ``height`` and ``width`` lines may come in either order; the ``type``
    value (``octile`` in every published map) is not used. Blank lines at the end of the
    file and a UTF-8 byte-order mark at its start are ignored.

    Raises
    ------
    ScenarioError
        Missing or unreadable file, not ASCII, bad header, wrong number of lines or
        characters, unknown terrain character; the message names the file and the line.
    """
    path = Path(path)
    raw = read_bytes(path, "MovingAI map")
    raw = raw.removeprefix(codecs.BOM_UTF8)  # a map edited in an editor that saves one (TOML and YAML files skip it too)
    try:
        text = raw.decode("ascii")
    except UnicodeDecodeError as e:
        raise ScenarioError(f"{path}: not an ASCII MovingAI map (byte 0x{raw[e.start]:02x} at offset {e.start})") from None
    lines = [ln.rstrip(" \t\r") for ln in text.split("\n")]
    head = lines[0].split()
    if len(head) != 2 or head[0] != "type":
        raise ScenarioError(f"{path}: line 1: expected the MovingAI header 'type octile', got {lines[0][:40]!r}")
    if len(lines) < 4:
        raise ScenarioError(f"{path}: truncated header: expected lines 'type', 'height', 'width', 'map', "
                            f"found {len(lines)} lines")
    first_dim = lines[1].split()[0] if lines[1].split() else ""
    order = ("width", "height") if first_dim == "width" else ("height", "width")
    dims = {order[0]: _header_int(lines, 1, order[0], path), order[1]: _header_int(lines, 2, order[1], path)}
    h, w = dims["height"], dims["width"]
    if lines[3].strip() != "map":
        raise ScenarioError(f"{path}: line 4: expected 'map', got {lines[3]!r}")
    if w * h > MAX_CELLS:
        raise ScenarioError(f"{path}: {w} x {h} cells exceeds the limit of {MAX_CELLS}")
    body = lines[4:]
    while body and body[-1] == "":
        body.pop()
    if len(body) < h:
        raise ScenarioError(f"{path}: the header says height {h} but the file has {len(body)} map lines")
    if len(body) > h:
        raise ScenarioError(f"{path}: line {5 + h}: unexpected data after the {h} map lines (height {h}): "
                            f"{body[h][:40]!r}")
    rows = body
    for y, row in enumerate(rows):
        if len(row) != w:
            raise ScenarioError(f"{path}: line {5 + y} has {len(row)} characters, expected {w} (width {w})")
    prob = characters.decode(rows, _TABLE)
    if isinstance(prob, characters.BadCharacter):
        raise ScenarioError(f"{path}: line {5 + prob.row}, column {prob.column}: unknown terrain character "
                            f"{prob.char!r}; allowed: {', '.join(map(repr, FREE))} free, "
                            f"{', '.join(map(repr, OCCUPIED))} occupied")
    return OccupancyGrid(prob, resolution=resolution, origin=origin)


def save_movingai(grid: OccupancyGrid, path: Path | str) -> None:
    """Write ``grid`` as a MovingAI map: '.' free, '@' occupied, row y = map line y.

    The format keeps only occupancy (``prob >= 0.5``): probabilities, resolution and
    origin are dropped (a warning is logged when they are not the format's default 1 m
    cells at origin (0, 0); give them back as the config's ``resolution`` and ``origin``).
    Loading the file gives ``OccupancyGrid.from_occupied(grid.occupied)``.

    Raises
    ------
    ScenarioError
        The file cannot be written.
    """
    path = Path(path)
    if grid.resolution != 1.0 or grid.origin != (0.0, 0.0):
        log.warning("MovingAI maps hold no scale: resolution %g and origin %s are not saved in %s (give them as "
                    "scenario.map.resolution and scenario.map.origin)", grid.resolution, grid.origin, path)
    rows = characters.encode(grid.occupied, ".", "@")
    text = f"type octile\nheight {grid.height}\nwidth {grid.width}\nmap\n" + "\n".join(rows) + "\n"
    try:
        path.write_text(text, encoding="ascii", newline="\n")
    except OSError as e:
        raise ScenarioError(f"cannot write MovingAI map {str(path)!r}: {e.strerror or e}") from e


__all__ = ["FREE", "OCCUPIED", "load_movingai", "read_movingai", "save_movingai"]
