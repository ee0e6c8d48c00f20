"""Two robots passing one cell apart on an open 8 x 7 grid: the window problem's smallest real case.

Robot 0 flies east along y = 2 and then turns south; robot 1 flies west along y = 3 and then
turns north. Each one's smoothest path swings out before its turn, that is towards the other:
only their relative corridor keeps them apart.
"""

from __future__ import annotations

import numpy as np

from mrfswarm.continuous.receding_horizon import RecedingHorizon, WindowRecord
from mrfswarm.maps import OccupancyGrid

PASSING = np.array([[a, b] for a, b in zip([(x, 2) for x in range(7)] + [(6, 1), (6, 0), (7, 0)],
                                            [(x, 3) for x in range(6, -1, -1)] + [(0, 4), (0, 5), (0, 6)])])
GRID = OccupancyGrid.from_occupied(np.zeros((8, 7), bool))


def first_window(rh: RecedingHorizon) -> tuple[int, int, int, np.ndarray, WindowRecord]:
    """(a, c, b) of ``rh``'s first window, its start state (at rest on the first cells) and a fresh record."""
    a, c, b = rh.windows()[0]
    start = np.zeros((rh.N, rh.cfg.derivative, rh.dim))
    start[:, 0] = rh.X[0]
    return a, c, b, start, WindowRecord(a, c, b)
