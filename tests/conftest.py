"""Helpers shared by the test modules, as fixtures."""

from __future__ import annotations

import numpy as np
import pytest

from mrfswarm.geometry import point_box_distance
from solvers.qp import QPCapabilities
from solvers.registry import Backend


def _dense_check(trajectories, grid, rate_hz: float = 500.0):
    """Brute force, independent of the planner and certificate: sample every robot at ``rate_hz``.

    Returns
    -------
    dict
        ``separation``: smallest distance between two robots (all pairs, every sample);
        ``clearance``: smallest distance from a robot's centre to an occupied cell's square
        (every occupied cell; inf without obstacles); ``off_map``: any sample off the map.
    """
    T = trajectories[0].duration
    t = np.linspace(0.0, T, int(np.ceil(T * rate_hz)) + 1)
    pts = np.stack([tr.evaluate(t) for tr in trajectories], axis=1)  # (S, N, 2)
    N = pts.shape[1]
    sep = np.inf
    for i in range(N - 1):
        d = np.linalg.norm(pts[:, i + 1:] - pts[:, i:i + 1], axis=-1)
        sep = min(sep, float(d.min()))
    occ = grid.cell_to_world(np.argwhere(grid.occupied))
    flat = pts.reshape(-1, 2)
    clr = np.inf
    for s in range(0, len(occ), 256):
        clr = min(clr, float(point_box_distance(flat[:, None, :], occ[None, s:s + 256], grid.resolution / 2).min()))
    x0, x1, y0, y1 = grid.extent
    off = bool(((flat[:, 0] < x0) | (flat[:, 0] > x1) | (flat[:, 1] < y0) | (flat[:, 1] > y1)).any())
    return {"separation": sep, "clearance": clr, "off_map": off}


@pytest.fixture(scope="session")
def dense_check():
    """``dense_check(trajectories, grid, rate_hz=500)``: brute-force sampled separation and clearance."""
    return _dense_check


@pytest.fixture
def missing_qp_backend():
    """A QP backend record named ``ghost`` whose module is not installed (extra ``ghost``)."""
    return Backend(name="ghost", entry=lambda *a: None, requires=("no_such_module_xyz",), extra="ghost",
                   capabilities=QPCapabilities(inequalities=True, warm_start=False, detects_infeasibility=False,
                                               sparse=True))
