"""The occupancy grid and the one place where world and cell coordinates meet.

Frame convention: arrays are indexed ``[ix, iy]`` (x index first), or ``[ix, iy, iz]`` for
a voxel map; cell ``(i, j[, k])`` is centred at ``origin + resolution * (i, j[, k])`` (metres)
and covers ``[c - res/2, c + res/2)`` on each axis. With the default 1 m cells at origin (0, 0),
cell (i, j) is centred at (i, j), as in the authors' data.

The dimension is data: a grid of ``d`` axes (2 or 3) takes and returns points and cells of
shape ``(..., d)``; nothing else differs.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from mrfswarm.errors import ScenarioError

log = logging.getLogger(__name__)

#: P(occupied) at or above which a cell is an obstacle (the paper's threshold).
OCCUPIED_THRESHOLD = 0.5

#: Largest number of cells a grid may have (10^8 float64 cells = 800 MB); larger sizes are
#: almost certainly a typo in a config or a corrupt file header, not a real scenario. Planning
#: on a map needs far more than the grid: the goal field's search graph peaks at about 600
#: bytes a cell (2.4 GB for 2000 x 2000 cells; README, "Limits worth knowing").
MAX_CELLS = 10**8

# A point within this many cells of a cell edge is treated as lying on it, so that a point
# computed as ``c + res/2`` lands in the next cell despite rounding of ``c`` and ``res``.
_EDGE_TOL = 1e-9


def _readonly(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class OccupancyGrid:
    """An occupancy grid (2-D cells or 3-D voxels): P(occupied) per cell, with its placement in the world.

    Parameters
    ----------
    prob
        P(occupied) in [0, 1], shape ``(W, H)`` indexed ``[ix, iy]``, or ``(W, H, D)`` indexed
        ``[ix, iy, iz]`` for a voxel map. Stored as a read-only float64 copy. Unknown cells
        loaded from files are 0.5, hence obstacles.
    resolution
        Cell side in metres, > 0.
    origin
        World coordinates (metres) of the CENTRE of cell (0, ...), one number per axis
        (``(0, 0)`` for a 2-D grid; a 3-D grid given a 2-D origin places z at 0).

    Notes
    -----
    Cell ``(i, j)`` is centred at ``origin + resolution * (i, j)`` and covers
    ``[c - resolution/2, c + resolution/2)`` on each axis. A cell is occupied when
    ``prob >= 0.5``. Grids compare equal when shape, ``prob``, resolution and origin
    are all exactly equal.
    """

    prob: np.ndarray
    resolution: float = 1.0
    origin: tuple[float, ...] = field(default=(0.0, 0.0))

    def __post_init__(self) -> None:
        try:
            prob = np.array(self.prob, dtype=np.float64)  # always a copy: the grid owns it
        except (TypeError, ValueError) as e:
            raise ScenarioError(f"occupancy grid: prob is not a numeric array ({e})") from e
        if prob.ndim not in (2, 3) or min(prob.shape) < 1:
            raise ScenarioError(f"occupancy grid: prob must have shape (W, H) or (W, H, D), each >= 1, "
                                f"got {prob.shape}")
        if prob.size > MAX_CELLS:
            raise ScenarioError(f"occupancy grid: {' x '.join(map(str, prob.shape))} cells exceeds {MAX_CELLS}")
        bad = ~(np.isfinite(prob) & (prob >= 0.0) & (prob <= 1.0))
        if bad.any():
            at = tuple(int(v) for v in np.argwhere(bad)[0])
            raise ScenarioError(f"occupancy grid: prob[{', '.join(map(str, at))}] = {float(prob[at])!r} "
                                "is not in [0, 1]")
        res = self.resolution
        if isinstance(res, bool) or not isinstance(res, (int, float, np.integer, np.floating)) \
                or not np.isfinite(res) or res <= 0:
            shown = res.item() if isinstance(res, np.generic) else res
            raise ScenarioError(f"occupancy grid: resolution = {shown!r} must be a finite number > 0")
        try:
            origin = tuple(float(v) for v in self.origin)
        except (TypeError, ValueError) as e:
            raise ScenarioError(f"occupancy grid: origin = {self.origin!r} must be {prob.ndim} numbers") from e
        if prob.ndim == 3 and len(origin) == 2:
            origin = origin + (0.0,)
        if len(origin) != prob.ndim or not all(np.isfinite(origin)):
            raise ScenarioError(f"occupancy grid: origin = {self.origin!r} must be {prob.ndim} finite numbers")
        object.__setattr__(self, "prob", _readonly(prob))
        object.__setattr__(self, "resolution", float(res))
        object.__setattr__(self, "origin", origin)

    @classmethod
    def from_occupied(cls, occupied: np.ndarray, resolution: float = 1.0,
                      origin: tuple[float, ...] = (0.0, 0.0)) -> OccupancyGrid:
        """A grid with P = 1 on ``occupied`` cells and 0 elsewhere (``occupied`` is (W, H) or (W, H, D) bool)."""
        occ = np.asarray(occupied)
        if occ.dtype != bool:
            raise ScenarioError(f"from_occupied: expected a boolean (W, H[, D]) array, got dtype {occ.dtype}")
        return cls(occ.astype(np.float64), resolution=resolution, origin=origin)

    # -- derived arrays and sizes -------------------------------------------------------

    @cached_property
    def occupied(self) -> np.ndarray:
        """Bool (W, H[, D]): ``prob >= 0.5`` (read-only)."""
        return _readonly(self.prob >= OCCUPIED_THRESHOLD)

    @cached_property
    def free(self) -> np.ndarray:
        """Bool (W, H[, D]): not occupied (read-only)."""
        return _readonly(~self.occupied)

    @property
    def shape(self) -> tuple[int, ...]:
        """``(W, H)`` or ``(W, H, D)`` in cells."""
        return tuple(self.prob.shape)

    @property
    def ndim(self) -> int:
        """The number of axes, 2 (cells) or 3 (voxels): the length of every point and cell index."""
        return self.prob.ndim

    @property
    def width(self) -> int:
        """W, the number of cells along x."""
        return self.prob.shape[0]

    @property
    def height(self) -> int:
        """H, the number of cells along y."""
        return self.prob.shape[1]

    @property
    def depth(self) -> int:
        """D, the number of cells along z (1 for a 2-D grid)."""
        return self.prob.shape[2] if self.prob.ndim == 3 else 1

    @property
    def extent(self) -> tuple[float, float, float, float]:
        """``(x0, x1, y0, y1)``: the world rectangle covered by the cells' edges (x and y only).

        For plotting: ``imshow(grid.prob.T, origin="lower", extent=grid.extent)``.
        """
        r, ox, oy = self.resolution, self.origin[0], self.origin[1]
        return (ox - r / 2, ox + (self.width - 0.5) * r, oy - r / 2, oy + (self.height - 0.5) * r)

    @property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """``(lo, hi)``, each ``(d,)``: the world box covered by the cells' edges."""
        o, r = np.asarray(self.origin), self.resolution
        return o - r / 2, o + (np.asarray(self.shape) - 0.5) * r

    def _check_points(self, what: str, p: np.ndarray, kind: str) -> None:
        if p.ndim < 1 or p.shape[-1] != self.ndim:
            raise ScenarioError(f"{what}: expected {kind} of shape (..., {self.ndim}), got {p.shape}")

    # -- world <-> cell -----------------------------------------------------------------

    def world_to_cell(self, p: np.ndarray) -> np.ndarray:
        """The cell containing each world point.

        Parameters
        ----------
        p
            World points, shape ``(..., d)``, metres (``d`` = :attr:`ndim`).

        Returns
        -------
        numpy.ndarray
            Integer cell indices ``(..., d)``; ``floor((p - origin) / res + 1/2)``, so a
            point at ``c + res/2`` belongs to the next cell. Points off the map give
            indices outside ``[0, W) x [0, H)`` (check with :meth:`in_bounds`).

        Raises
        ------
        ScenarioError
            ``p`` is not ``(..., d)`` or holds a non-finite value.
        """
        p = np.asarray(p, dtype=np.float64)
        self._check_points("world_to_cell", p, "points")
        if not np.isfinite(p).all():
            raise ScenarioError("world_to_cell: points must be finite")
        u = (p - np.asarray(self.origin)) / self.resolution
        # a point 1e300 m away is off the map as one 2^62 cells away is: clipped, it casts to int64 without numpy's
        # "invalid value" warning beside the one-line error (a tour)
        return np.floor(np.clip(u, -2.0**62, 2.0**62) + (0.5 + _EDGE_TOL)).astype(np.int64)

    def cell_to_world(self, ij: np.ndarray) -> np.ndarray:
        """The world coordinates (metres) of each cell's centre; ``ij`` is ``(..., d)``."""
        ij = np.asarray(ij)
        self._check_points("cell_to_world", ij, "cells")
        return np.asarray(self.origin) + self.resolution * ij.astype(np.float64)

    def in_bounds(self, ij: np.ndarray) -> np.ndarray:
        """Bool ``(...)``: whether each cell ``(..., d)`` lies on the map."""
        ij = np.asarray(ij)
        self._check_points("in_bounds", ij, "cells")
        i, j = ij[..., 0], ij[..., 1]
        inside = (i >= 0) & (i < self.width) & (j >= 0) & (j < self.height)
        if self.ndim == 3:
            inside &= (ij[..., 2] >= 0) & (ij[..., 2] < self.depth)
        return inside

    def occupied_as(self, ij: np.ndarray) -> str:
        """What makes the occupied cell ``ij`` (d,) an obstacle, for an error: ``"an obstacle"``, or, where the map
        file left it unknown (P = 0.5, ROS grey 205), ``"a cell the map leaves unknown (an obstacle)"``; a start in
        a SLAM map's unexplored part read "inside an obstacle" (a map tour)."""
        p = float(self.prob[tuple(np.asarray(ij, dtype=np.intp))])
        return "a cell the map leaves unknown (an obstacle)" if p == 0.5 else "an obstacle"

    def is_free(self, ij: np.ndarray) -> np.ndarray:
        """Bool ``(...)``: whether each cell ``(..., d)`` is on the map and free (False off the map)."""
        ij = np.asarray(ij)
        inside = self.in_bounds(ij)
        if ij.dtype.kind not in "iu":
            if not np.all(ij[inside] == np.floor(ij[inside])):
                raise ScenarioError("is_free: cell indices must be integers")
        idx = tuple(np.clip(ij[..., a], 0, n - 1).astype(np.intp) for a, n in enumerate(self.shape))
        return inside & self.free[idx]

    def snap(self, p: np.ndarray) -> np.ndarray:
        """World points ``(..., d)`` moved to the centre of the cell containing them.

        Points off the map snap to the centre of the (off-map) lattice cell containing
        them; nothing is clamped.
        """
        return self.cell_to_world(self.world_to_cell(p))

    # -- comparison ---------------------------------------------------------------------

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, OccupancyGrid):
            return NotImplemented
        return (self.shape == other.shape and self.resolution == other.resolution
                and self.origin == other.origin and bool(np.array_equal(self.prob, other.prob)))

    def __reduce__(self):
        # rebuild through __init__ so that an unpickled grid (Dask workers) is validated and read-only again
        return (type(self), (np.asarray(self.prob), self.resolution, self.origin))

    __hash__ = None  # type: ignore[assignment]  # holds an array; equal grids need not hash alike

    def __repr__(self) -> str:
        return (f"OccupancyGrid({' x '.join(map(str, self.shape))} cells, resolution={self.resolution}, "
                f"origin={self.origin}, occupied={int(self.occupied.sum())})")
