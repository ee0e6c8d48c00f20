"""Voxel files: a NumPy array (``.npy``) and binvox (``.binvox``), read and written.

``npy``
    NumPy's own file format (``numpy.save``), read with ``numpy.lib.format.read_array``
    (no pickles): an array of shape (W, H, D) indexed ``[ix, iy, iz]``, or (W, H) indexed
    ``[ix, iy]`` for a 2-D map, either boolean (True = occupied) or floating point
    (P(occupied) in [0, 1], occupied at >= 0.5).
``binvox``
    Patrick Min's binvox format (https://www.patrickmin.com/binvox/binvox.html), what
    the ``binvox`` voxelizer and many mesh tools write: a text header (``dim``,
    ``translate``, ``scale``) and run-length encoded voxels. Read and written with
    trimesh (``trimesh.exchange.binvox``, the ``voxels`` extra), which orders the axes
    x, y, z of the voxelized model; a model made with y up must be turned z up before
    voxelizing. Binvox grids are cubes (``dim d d d``, as the voxelizer writes them).

Neither file places the voxels in a map frame (binvox's ``translate`` and ``scale`` are
the voxelizer's normalization of the model, usually into a unit cube): as for MovingAI
maps, the config's ``resolution`` (metres per voxel, default 1.0) and ``origin`` (the
centre of voxel (0, 0, 0), default [0, 0, 0]) place them. Voxels are cubes.
"""

from __future__ import annotations

import io
import logging
from pathlib import Path
from typing import Any

import numpy as np

from mrfswarm.errors import ScenarioError
from mrfswarm.file_input import read_bytes
from mrfswarm.maps import extrusion
from mrfswarm.maps.grid import MAX_CELLS, OccupancyGrid
from mrfswarm.maps.spec import PREFIX, check_keys, file_path, placement

log = logging.getLogger(__name__)

_KEYS = ("kind", "path", "resolution", "origin")
_TRIMESH = "reading and writing .binvox files needs trimesh: pip install 'mrfswarm[voxels]'"


def load_npy(spec: dict, base_dir: Path) -> OccupancyGrid:
    """``{kind="npy", path="x.npy"}``: a (W, H, D) or (W, H) NumPy array, True (or P >= 0.5) occupied.

    A (W, H) array takes ``extrude`` as every 2-D map does (:mod:`mrfswarm.maps.extrusion`); whether the map is
    2-D is known once the file is read, so the key is taken here, not by :func:`mrfswarm.maps.load_map`.
    """
    check_keys(spec, (*_KEYS, extrusion.KEY), PREFIX, required=("path",))
    path = file_path(spec, base_dir)
    flat = {k: v for k, v in spec.items() if k != extrusion.KEY}
    placement({k: v for k, v in flat.items() if k != "origin"})  # the resolution before the file; its origin's
    prob = _read_npy(path)  # length is the array's number of axes
    _check_axes(prob, path, (2, 3))  # a 1-D or 4-D array is the file's fault, not the origin's
    if extrusion.KEY in spec and prob.ndim == 2:
        return extrusion.load_extruded(spec, base_dir, lambda plane, _: _grid(prob, path, *placement(plane), dims=(2,)))
    res, origin = placement(flat, prob.ndim)
    grid = _grid(prob, path, res, origin, dims=(2, 3))
    return extrusion.extrude(grid, extrusion.depth(spec[extrusion.KEY])) if extrusion.KEY in spec else grid


def load_binvox(spec: dict, base_dir: Path) -> OccupancyGrid:
    """``{kind="binvox", path="x.binvox"}``: a binvox file, its voxels placed by the config."""
    check_keys(spec, _KEYS, PREFIX, required=("path",))
    res, origin = placement(spec, 3)
    return read_binvox(file_path(spec, base_dir), resolution=res, origin=origin)


def _grid(prob: np.ndarray, path: Path, resolution: float, origin: tuple[float, ...],
          dims: tuple[int, ...] = (3,)) -> OccupancyGrid:
    _check_axes(prob, path, dims)
    if prob.size > MAX_CELLS:
        raise ScenarioError(f"{path}: {' x '.join(map(str, prob.shape))} cells exceeds the limit of {MAX_CELLS}")
    try:
        return OccupancyGrid(prob, resolution=resolution, origin=origin)
    except ScenarioError as e:  # values outside [0, 1], an empty axis: say which file
        raise ScenarioError(f"{path}: {e}") from None


def _check_axes(prob: np.ndarray, path: Path, dims: tuple[int, ...]) -> None:
    if prob.ndim not in dims:
        shapes = " or ".join({2: "a map (W, H)", 3: "a voxel map (W, H, D)"}[d] for d in dims)
        raise ScenarioError(f"{path}: array of shape {prob.shape}: expected {shapes}")


def read_npy(path: Path | str, resolution: float = 1.0,
             origin: tuple[float, ...] | None = None) -> OccupancyGrid:
    """Read a ``.npy`` array: bool (True occupied) or float P(occupied), shape (W, H, D) (voxels) or (W, H) (a
    2-D map, indexed ``[ix, iy]``); ``origin`` defaults to zeros of the array's axes.

    Raises
    ------
    ScenarioError
        Missing or unreadable file, not a ``.npy`` file (or a pickled one), another
        dtype, another number of axes, values outside [0, 1]; names the file.
    """
    path = Path(path)
    prob = _read_npy(path)
    return _grid(prob, path, resolution, tuple([0.0] * prob.ndim) if origin is None else origin, dims=(2, 3))


def _read_npy(path: Path) -> np.ndarray:
    """The array of a ``.npy`` file as float P(occupied) (any shape: :func:`_grid` checks it)."""
    raw = read_bytes(path, "map file")
    try:
        arr = np.lib.format.read_array(io.BytesIO(raw), allow_pickle=False)
    except (ValueError, EOFError, OSError, SyntaxError, TypeError) as e:
        detail = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        raise ScenarioError(f"{path}: not a NumPy .npy array ({detail})") from None
    if arr.dtype == bool:
        prob = arr.astype(np.float64)
    elif arr.dtype.kind == "f":
        prob = arr.astype(np.float64)
    else:
        raise ScenarioError(f"{path}: dtype {arr.dtype}: expected bool (True = occupied) or float P(occupied) in "
                            f"[0, 1]; save a 0/1 array as array.astype(bool)")
    return prob


def read_binvox(path: Path | str, resolution: float = 1.0,
                origin: tuple[float, ...] = (0.0, 0.0, 0.0)) -> OccupancyGrid:
    """Read a ``.binvox`` file with trimesh: voxel (i, j, k) of the model is cell (i, j, k).

    Raises
    ------
    ScenarioError
        Missing, unreadable or malformed file (header, run lengths), not a cube; names the file.
        Also when trimesh is not installed (the message says how to install it).
    """
    path = Path(path)
    binvox = _trimesh_binvox()
    raw = read_bytes(path, "voxel file")
    try:
        parsed = binvox.parse_binvox(io.BytesIO(raw), writeable=True)
        shape = tuple(int(n) for n in parsed.shape)
        if len(shape) != 3 or min(shape) < 1 or len(set(shape)) != 1 or shape[0] ** 3 > MAX_CELLS:
            raise ScenarioError(f"{path}: binvox dim {' '.join(map(str, shape))}: expected a cube, dim d d d with "
                                f"1 <= d**3 <= {MAX_CELLS} (the binvox voxelizer's grids; tools disagree on the axis "
                                f"order of other shapes: save those as .npy)")
        runs = parsed.rle_data
        held = int(runs[1::2].astype(np.int64).sum())  # (value, count) byte pairs
        if len(runs) % 2 or held != shape[0] ** 3:
            raise ScenarioError(f"{path}: binvox data holds {held} voxels in {len(runs)} bytes of (value, count) "
                                f"pairs, expected {shape[0] ** 3} (dim {' '.join(map(str, shape))})")
        with np.errstate(divide="ignore", invalid="ignore"):  # trimesh's unused transform divides by d - 1
            # binvox's voxel order (x slowest, then z, then y); trimesh turns it to x, y, z
            grid = binvox.voxel_from_binvox(runs, shape, axis_order="xzy")
        occupied = np.asarray(grid.encoding.dense, dtype=bool)
    except ScenarioError:
        raise
    except (OSError, ValueError, IndexError, TypeError, UnicodeDecodeError, AssertionError) as e:
        detail = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        raise ScenarioError(f"{path}: not a binvox file ({detail})") from None
    return _grid(occupied.astype(np.float64), path, resolution, origin)


def _trimesh_binvox() -> Any:
    """``trimesh.exchange.binvox``, imported on use (a ScenarioError saying how to install it when it is not)."""
    try:
        from trimesh.exchange import binvox
    except ModuleNotFoundError as e:
        if e.name is not None and e.name.split(".")[0] == "trimesh":
            raise ScenarioError(_TRIMESH) from None
        raise
    return binvox


def save_voxels(grid: OccupancyGrid, path: Path | str) -> None:
    """Write a voxel grid's occupancy as ``.npy`` (bool) or ``.binvox`` (trimesh), by the file's suffix.

    Only occupancy is kept (``prob >= 0.5``); resolution and origin are not (give them
    back as the config's ``resolution`` and ``origin``).

    Raises
    ------
    ScenarioError
        Not a 3-D grid, another suffix, or the file cannot be written.
    """
    path = Path(path)
    if grid.ndim != 3:
        raise ScenarioError(f"save_voxels: a voxel file holds a 3-D grid, got {' x '.join(map(str, grid.shape))} cells")
    suffix = path.suffix.lower()
    if suffix == ".npy":
        buf = io.BytesIO()
        np.save(buf, np.asarray(grid.occupied))
        data = buf.getvalue()
    elif suffix == ".binvox":
        if len(set(grid.shape)) != 1:
            raise ScenarioError(f"save_voxels: {str(path)!r}: binvox holds cubes (d x d x d voxels), got "
                                f"{' x '.join(map(str, grid.shape))}; save it as .npy")
        binvox = _trimesh_binvox()
        from trimesh.voxel import VoxelGrid

        with np.errstate(divide="ignore", invalid="ignore"):
            data = binvox.export_binvox(VoxelGrid(np.asarray(grid.occupied)))
    else:
        raise ScenarioError(f"save_voxels: {str(path)!r}: the suffix must be .npy or .binvox")
    try:
        path.write_bytes(data)
    except OSError as e:
        raise ScenarioError(f"cannot write voxel file {str(path)!r}: {e.strerror or e}") from e


__all__ = ["load_binvox", "load_npy", "read_binvox", "read_npy", "save_voxels"]
