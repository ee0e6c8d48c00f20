"""ROS map_server maps: a YAML file of metadata plus an image, read and written.

Reference: ROS wiki, map_server, "YAML format" (http://wiki.ros.org/map_server) and
nav_msgs/MapMetaData.msg. The YAML keys are ``image`` (path relative to the YAML
file), ``resolution`` (m/pixel), ``origin`` [x, y, yaw] -- "the 2-D pose of the
lower-left pixel in the map"; MapMetaData makes it precise: "the real-world pose of the
bottom left corner of cell (0,0)" -- ``occupied_thresh``, ``free_thresh``, ``negate`` and
optional ``mode`` (trinary, scale or raw; default trinary).

Conversion to an :class:`OccupancyGrid`:

- The image's top row is the map's highest y: image row r, column c is cell
  (c, H - 1 - r) (map_server fills ``data[width * (height - r - 1) + c]``).
- ROS's origin is a cell CORNER; ours is the centre of cell (0, 0):
  ``origin = (x + resolution/2, y + resolution/2)``.
- A nonzero yaw (a rotated map) is refused.
- The YAML's resolution and origin are the map's frame; the config's
  ``scenario.map.resolution`` and ``scenario.map.origin`` (our origin: the centre of cell
  (0, 0)) may state them but not change them: a value that disagrees is a
  :class:`ConfigError` naming the key, both values and the YAML. Rescaling a map
  recorded at one resolution would put its walls where they are not, and moving it
  would take it out of the frame the robots localize in.
- With grey value v (mean of the colour channels, 0..255), p = (255 - v)/255, or
  v/255 when ``negate``. Trinary: p > occupied_thresh -> 1.0, p < free_thresh -> 0.0,
  otherwise unknown -> 0.5. Scale: the same, but between the thresholds
  P = rint(100 (p - free)/(occupied - free)) / 100, and a pixel that is not fully opaque
  is unknown (0.5), as in Nav2's map_io. Raw: round(v) in 0..100 is a percentage,
  anything above 100 is unknown (0.5); ``negate`` is ignored in raw mode, as in Nav2.

UNKNOWN CELLS ARE OBSTACLES: their P = 0.5 meets the occupied threshold (P >= 0.5). This
is deliberately conservative: the swarm never plans through space nobody has mapped.
Alpha channels are ignored except by scale mode.
"""

from __future__ import annotations

import logging
import math
from pathlib import Path
from typing import Any

import numpy as np

from mrfswarm.errors import ConfigError, ScenarioError
from mrfswarm.maps.grid import OccupancyGrid
from mrfswarm.maps.raster import read_raster, write_pgm
from mrfswarm.maps.spec import PREFIX, check_keys, file_path, placement

log = logging.getLogger(__name__)

MODES = ("trinary", "scale", "raw")
REQUIRED = ("image", "resolution", "origin", "negate", "occupied_thresh", "free_thresh")
OPTIONAL = ("mode",)
UNKNOWN = 0.5

# |yaw| below this (radians) counts as zero; map savers print yaw with %f or as -0.0.
_YAW_TOL = 1e-9

# Grey values written by save_ros, as ROS map_saver writes them.
_FREE_GREY, _UNKNOWN_GREY, _OCCUPIED_GREY = 254, 205, 0


def load_ros(spec: dict, base_dir: Path) -> OccupancyGrid:
    """``{kind="ros", path=...}``: a ROS map_server YAML file, path relative to ``base_dir``.

    Optional ``resolution`` and ``origin`` (centre of cell (0, 0)) must agree with the
    YAML's (module docstring).
    """
    check_keys(spec, ("kind", "path", "resolution", "origin"), PREFIX, required=("path",))
    res, (ox, oy) = placement(spec)  # checks the values' types before the file is read
    path = file_path(spec, base_dir)
    grid = read_ros(path)
    if "resolution" in spec and not _same(res, grid.resolution):
        raise ConfigError(f"{PREFIX}.resolution = {spec['resolution']!r} disagrees with the ROS map {str(path)!r} "
                          f"(resolution {grid.resolution:g} m); a ROS map's scale comes from its YAML: remove the key "
                          f"or fix the YAML")
    if "origin" in spec and not (_same(ox, grid.origin[0]) and _same(oy, grid.origin[1])):
        r = grid.resolution
        raise ConfigError(f"{PREFIX}.origin = {spec['origin']!r} disagrees with the ROS map {str(path)!r}: its cell "
                          f"(0, 0) is centred at [{grid.origin[0]:g}, {grid.origin[1]:g}] (the YAML's origin "
                          f"[{grid.origin[0] - r / 2:g}, {grid.origin[1] - r / 2:g}] is that cell's corner); "
                          f"remove the key or give that centre")
    return grid


def _same(a: float, b: float) -> bool:
    return math.isclose(a, b, rel_tol=1e-9, abs_tol=1e-9)


def _number(doc: dict, key: str, path: Path) -> float:
    value = doc[key]
    if isinstance(value, str):  # YAML 1.1 reads "1e-05" as a string; yaml-cpp reads it as a number
        try:
            value = float(value)
        except ValueError:
            pass
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ScenarioError(f"{path}: {key} = {doc[key]!r} must be a finite number")
    return float(value)


def _first_line(e: BaseException) -> str:
    text = str(e).strip()
    return text.splitlines()[0] if text else type(e).__name__


def _metadata(path: Path) -> dict[str, Any]:
    import yaml  # noqa: PLC0415 (only ROS maps need it)

    try:
        text = path.read_text(encoding="utf-8")
    except OSError as e:
        raise ScenarioError(f"cannot read ROS map YAML {str(path)!r}: {e.strerror or e}") from e
    except UnicodeDecodeError as e:
        image = path.suffix.lower() in (".pgm", ".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")
        raise ScenarioError(f"{path}: not a UTF-8 text file (byte offset {e.start}); expected ROS map YAML" + (
            " (this is its image: give scenario.map.path the map's .yaml, whose image: names it)" if image else "")
        ) from None
    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f" at line {mark.line + 1}" if mark is not None else ""
        problem = getattr(e, "problem", None) or type(e).__name__
        raise ScenarioError(f"{path}: invalid YAML{where}: {problem}") from None
    except (ValueError, RecursionError) as e:  # e.g. "image: 2001-13-01" (a bad date), absurd nesting
        raise ScenarioError(f"{path}: invalid YAML: {type(e).__name__}: {_first_line(e)}") from None
    if not isinstance(doc, dict):
        raise ScenarioError(f"{path}: expected a YAML mapping with keys {', '.join(REQUIRED)}, got {type(doc).__name__}")
    for key in REQUIRED:
        if key not in doc:
            raise ScenarioError(f"{path}: missing key {key!r} (ROS map YAML needs {', '.join(REQUIRED)})")
    extra = [k for k in doc if k not in REQUIRED + OPTIONAL]
    if extra:
        log.debug("%s: ignoring keys %s (not used by map_server)", path, extra)

    image = doc["image"]
    if not isinstance(image, str) or not image.strip():
        raise ScenarioError(f"{path}: image = {image!r} must be a non-empty file name")
    res = _number(doc, "resolution", path)
    if res <= 0:
        raise ScenarioError(f"{path}: resolution = {doc['resolution']!r} must be > 0")
    origin = doc["origin"]
    if not isinstance(origin, list) or len(origin) != 3:
        raise ScenarioError(f"{path}: origin = {origin!r} must be a list [x, y, yaw]")
    ox, oy, yaw = (_number({"origin": v}, "origin", path) for v in origin)
    if abs(yaw) > _YAW_TOL:
        raise ScenarioError(f"{path}: origin yaw = {origin[2]!r} rad is not supported (rotated maps); "
                            f"rotate the image instead and set yaw to 0")
    negate = doc["negate"]
    if isinstance(negate, bool):
        negate = int(negate)
    if negate not in (0, 1) or isinstance(negate, float):
        raise ScenarioError(f"{path}: negate = {doc['negate']!r} must be 0 or 1")
    occ_th = _number(doc, "occupied_thresh", path)
    free_th = _number(doc, "free_thresh", path)
    if not 0.0 <= free_th < occ_th <= 1.0:
        raise ScenarioError(f"{path}: free_thresh = {free_th} and occupied_thresh = {occ_th} must satisfy "
                            f"0 <= free_thresh < occupied_thresh <= 1")
    mode = doc.get("mode", "trinary")
    if not isinstance(mode, str) or mode.lower() not in MODES:
        raise ScenarioError(f"{path}: mode = {mode!r} must be one of {', '.join(MODES)}")
    image_path = Path(image).expanduser()
    if not image_path.is_absolute():
        image_path = path.parent / image_path
    return {"image": image_path, "resolution": res, "origin": (ox, oy), "negate": bool(negate),
            "occupied_thresh": occ_th, "free_thresh": free_th, "mode": mode.lower()}


def occupancy(grey: np.ndarray, alpha: np.ndarray | None, *, mode: str, negate: bool,
              occupied_thresh: float, free_thresh: float) -> np.ndarray:
    """P(occupied) per pixel from grey values (0..255), map_server's rules (see the module)."""
    if mode == "raw":
        v = np.round(grey)
        return np.where(v <= 100, v / 100.0, UNKNOWN)
    p = grey / 255.0 if negate else (255.0 - grey) / 255.0
    if mode == "trinary":
        middle = np.full_like(p, UNKNOWN)
    else:
        middle = np.rint(100.0 * (p - free_thresh) / (occupied_thresh - free_thresh)) / 100.0
    out = np.where(p > occupied_thresh, 1.0, np.where(p < free_thresh, 0.0, middle))
    if mode == "scale" and alpha is not None:  # Nav2: a pixel that is not fully opaque is unknown
        out = np.where(alpha < 255, UNKNOWN, out)
    return out


def read_ros(path: Path | str) -> OccupancyGrid:
    """Read a ROS map_server map (YAML + PGM/PNG image); see the module for the conversion.

    Raises
    ------
    ScenarioError
        Missing or malformed YAML, missing keys, bad values, nonzero yaw, a missing,
        unreadable or 16-bit image; the message names the file.
    """
    path = Path(path)
    meta = _metadata(path)
    raster = read_raster(meta["image"])
    prob = occupancy(raster.grey, raster.alpha, mode=meta["mode"], negate=meta["negate"],
                     occupied_thresh=meta["occupied_thresh"], free_thresh=meta["free_thresh"])
    res = meta["resolution"]
    ox, oy = meta["origin"]
    # image row r is y = H - 1 - r; then index [x, y]
    return OccupancyGrid(np.ascontiguousarray(prob[::-1].T), resolution=res, origin=(ox + res / 2, oy + res / 2))


def save_ros(grid: OccupancyGrid, yaml_path: Path | str) -> None:
    """Write ``grid`` as a ROS map: ``yaml_path`` plus an 8-bit PGM of the same stem.

    Trinary, as ROS map_saver writes: occupied cells black (0), free cells 254, cells
    with P exactly 0.5 (unknown) grey 205; thresholds 0.65 / 0.196. Loading the files
    gives back the occupancy and every P in {0, 0.5, 1}; other P become 0 or 1 by the
    0.5 threshold. Resolution and origin are kept (origin up to floating-point rounding
    of the half-cell shift).

    Raises
    ------
    ScenarioError
        The files cannot be written, or ``yaml_path`` ends in ``.pgm``.
    """
    import yaml  # noqa: PLC0415

    yaml_path = Path(yaml_path)
    image_path = yaml_path.with_suffix(".pgm")
    if image_path == yaml_path:
        raise ScenarioError(f"save_ros: {str(yaml_path)!r} is the image's name; give the YAML file's path")
    pix = np.where(grid.prob == UNKNOWN, _UNKNOWN_GREY, np.where(grid.occupied, _OCCUPIED_GREY, _FREE_GREY))
    write_pgm(image_path, pix.T[::-1])  # (W, H) [x, y] -> rows top (y = H - 1) to bottom
    r = grid.resolution
    meta = {
        "image": image_path.name,
        "mode": "trinary",
        "resolution": r,
        "origin": [grid.origin[0] - r / 2, grid.origin[1] - r / 2, 0.0],
        "negate": 0,
        "occupied_thresh": 0.65,
        "free_thresh": 0.196,
    }
    try:
        yaml_path.write_text(yaml.safe_dump(meta, sort_keys=False, default_flow_style=None), encoding="utf-8")
    except OSError as e:
        raise ScenarioError(f"cannot write ROS map YAML {str(yaml_path)!r}: {e.strerror or e}") from e
