"""Static fields for tests on random maps, with either goal distance."""

from __future__ import annotations

import numpy as np

from mrfswarm.config import GoalPotentialConfig, ObstaclePotentialConfig
from mrfswarm.discrete.motion import moves_clear, stencil
from mrfswarm.discrete.potentials import static_field


def random_map_static(free: np.ndarray, goal: np.ndarray | None, start: np.ndarray, distance: str,
                      order: int = 2) -> np.ndarray:
    """rho_S of a random map with ``distance`` ("geodesic" or "euclidean").

    A random map can cut robots off from the goal; the geodesic field is ``inf`` there
    (the planner refuses such a start, tested in discrete/test_navigation.py), so those
    draws fall back to the paper's straight-line field, which is finite everywhere.
    """
    prob = (~free).astype(float)
    s = static_field(prob, goal, 1.0, GoalPotentialConfig(distance=distance), ObstaclePotentialConfig(), order)
    if np.isfinite(s[tuple(np.asarray(start).T)]).all():
        return s
    return static_field(prob, goal, 1.0, GoalPotentialConfig(distance="euclidean"), ObstaclePotentialConfig(), order)


def local_minima(free: np.ndarray, field: np.ndarray, order: int) -> list[tuple[int, int]]:
    """Free cells from which no clear move of the order-n stencil lowers ``field`` (brute force)."""
    out = []
    off = stencil(order)
    cells = np.argwhere(free & np.isfinite(field))
    ok = moves_clear(free, cells, np.broadcast_to(np.arange(len(off)), (len(cells), len(off))), order)
    for c, row in zip(cells, ok):
        lower = [field[tuple(c + o)] < field[tuple(c)] for o, k in zip(off, row) if k]
        if not any(lower):
            out.append(tuple(int(v) for v in c))
    return out
