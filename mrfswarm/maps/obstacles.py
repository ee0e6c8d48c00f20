"""An index over a grid's obstacles, built once per scenario and queried in O(1) per rectangle.

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
        sat = np.zeros((free.shape[0] + 1, free.shape[1] + 1), dtype=np.int64)
        sat[1:, 1:] = free.cumsum(axis=0).cumsum(axis=1)
        self._sat = sat

    def occupied_count(self, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """Occupied cells (off-map cells included) in the cell rectangles ``lo..hi`` (inclusive).

        Parameters
        ----------
        lo, hi
            (..., 2) integer cell indices; an empty rectangle (``hi < lo`` on an axis) has 0.
        """
        lo = np.asarray(lo, dtype=np.int64)
        hi = np.asarray(hi, dtype=np.int64)
        W, H = self.grid.shape
        area = np.prod(np.maximum(hi - lo + 1, 0), axis=-1)
        x0 = np.clip(lo[..., 0], 0, W)
        y0 = np.clip(lo[..., 1], 0, H)
        x1 = np.clip(hi[..., 0] + 1, 0, W)
        y1 = np.clip(hi[..., 1] + 1, 0, H)
        x1, y1 = np.maximum(x1, x0), np.maximum(y1, y0)
        s = self._sat
        free = s[x1, y1] - s[x0, y1] - s[x1, y0] + s[x0, y0]
        return area - free

    def is_occupied(self, ij: np.ndarray) -> np.ndarray:
        """Bool (...): occupied or off the map, for integer cells ``ij`` (..., 2)."""
        return ~self.grid.is_free(np.asarray(ij, dtype=np.int64))
