"""An index over a grid's obstacles, built once per scenario and queried in O(1) per box.

A box is a rectangle of cells on a 2-D grid, a cuboid of voxels on a 3-D one.

Everything off the map counts as occupied: a robot must stay on the map, so a query that
reaches past the edge sees a wall there.
"""

from __future__ import annotations

import numpy as np

from mrfswarm.maps.grid import OccupancyGrid


class ObstacleIndex:
    """Summed-area table of a grid's free cells.

    Parameters
    ----------
    grid
        The occupancy grid.
    """

    def __init__(self, grid: OccupancyGrid) -> None:
        self.grid = grid
        free = grid.free.astype(np.int64)
        sat = np.zeros(tuple(n + 1 for n in free.shape), dtype=np.int64)
        for axis in range(free.ndim):
            free = free.cumsum(axis=axis)
        sat[(slice(1, None),) * free.ndim] = free
        self._sat = sat
        # inclusion-exclusion over the box's 2^d corners: (corner picks hi on these axes, its sign)
        d = free.ndim
        self._corners = [(tuple(bool(c >> a & 1) for a in range(d)), (-1) ** (d - bin(c).count("1")))
                         for c in range(2**d)]

    def occupied_count(self, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """Occupied cells (off-map cells included) in the cell boxes ``lo..hi`` (inclusive).

        Parameters
        ----------
        lo, hi
            (..., d) integer cell indices; an empty box (``hi < lo`` on an axis) has 0.
        """
        lo = np.asarray(lo, dtype=np.int64)
        hi = np.asarray(hi, dtype=np.int64)
        area = np.prod(np.maximum(hi - lo + 1, 0), axis=-1)
        a = [np.clip(lo[..., k], 0, n) for k, n in enumerate(self.grid.shape)]
        b = [np.maximum(np.clip(hi[..., k] + 1, 0, n), a[k]) for k, n in enumerate(self.grid.shape)]
        s = self._sat
        free = sum(sign * s[tuple(b[k] if up else a[k] for k, up in enumerate(pick))]
                   for pick, sign in self._corners)
        return area - free

    def is_occupied(self, ij: np.ndarray) -> np.ndarray:
        """Bool (...): occupied or off the map, for integer cells ``ij`` (..., d)."""
        return ~self.grid.is_free(np.asarray(ij, dtype=np.int64))
