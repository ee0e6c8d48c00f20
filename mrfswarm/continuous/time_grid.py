"""The common time grid: nominal step durations and the durations at which a rest-to-rest flight is feasible.

Step j of the discrete plan is flown by every robot during :math:`[t_j, t_{j+1}]`. Its
nominal duration is the step's longest move (at least one cell) over the cruise
``speed``. The *witness* duration is long enough for every robot to fly its own discrete
move rest to rest (the degree-(2q-1) smooth step, all knot derivatives zero) with every
velocity, acceleration and jerk control point inside the limit octagons: that flight
satisfies every constraint of the window problem, so a window whose new steps last at
least this long always has a feasible point.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from mrfswarm.continuous.formulation import LIMIT_ORDERS, OCTAGON_INNER, piece_maps


def nominal_durations(paths: np.ndarray, resolution: float, speed: float, acceleration: float) -> np.ndarray:
    r"""(T,) nominal step durations: a trapezoidal speed profile along the steps' longest moves.

    Step j covers :math:`L_j` = its longest move (at least one cell, in metres); the
    swarm's nominal progress along :math:`s = \sum L_j` speeds up from rest at
    ``acceleration`` to ``speed``, cruises, and slows down to rest at the end (a triangle
    when the flight is too short to reach ``speed``). Step j lasts from the time the
    profile reaches :math:`s_j` to the time it reaches :math:`s_{j+1}`.
    """
    moves = np.hypot(*np.diff(np.asarray(paths, dtype=float), axis=0).transpose(2, 0, 1))  # (T, N)
    if moves.size == 0:
        return np.zeros(0)
    L = np.maximum(moves.max(axis=1), 1.0) * resolution
    s = np.concatenate([[0.0], np.cumsum(L)])
    total = s[-1]
    v = min(speed, float(np.sqrt(acceleration * total)))  # peak speed (a triangle if speed is not reached)
    ramp = v * v / (2 * acceleration)

    def time_at(x: np.ndarray) -> np.ndarray:
        up = np.sqrt(2 * np.minimum(x, ramp) / acceleration)
        cruise = np.clip(x - ramp, 0.0, total - 2 * ramp) / v
        down_dist = np.clip(x - (total - ramp), 0.0, ramp)
        down = (v - np.sqrt(np.maximum(v * v - 2 * acceleration * down_dist, 0.0))) / acceleration
        return up + cruise + down

    return np.diff(time_at(s))


@lru_cache(maxsize=16)
def rest_step_peaks(degree: int, derivative: int) -> tuple[float, ...]:
    """Largest control-point norm of derivatives 1, 2, 3 of a unit rest-to-rest step of unit duration."""
    pm = piece_maps(degree, derivative)
    k = pm.evaluate(np.array([1.0]))
    z = np.zeros(pm.nz)
    z[pm.derivative] = 1.0  # the position at tau = 1; every other knot derivative (and bubble) is 0
    peaks = []
    for r in LIMIT_ORDERS:
        rows = pm.rows[r]
        K = k[pm.k_offset[r]:pm.k_offset[r] + rows * pm.nz].reshape(pm.nz, rows).T
        peaks.append(float(np.abs(K @ z).max()))
    return tuple(peaks)


def witness_durations(paths: np.ndarray, resolution: float, limits: tuple[float, float, float], degree: int,
                      derivative: int, margin: float = 1e-6) -> np.ndarray:
    """(T,) durations at which every robot's rest-to-rest move meets the limits by its control points.

    A move of length L flown in time T has r-th derivative control points of norm
    ``peak_r L / T^r``; each must fit in the octagon of inner radius
    ``cos(pi/8) limit_r (1 - margin)``.
    """
    moves = np.hypot(*np.diff(np.asarray(paths, dtype=float), axis=0).transpose(2, 0, 1))
    L = moves.max(axis=1, initial=0.0) * resolution
    out = np.zeros_like(L)
    for r, peak, lim in zip(LIMIT_ORDERS, rest_step_peaks(degree, derivative), limits):
        out = np.maximum(out, (peak * L / (OCTAGON_INNER * lim * (1 - margin))) ** (1.0 / r))
    return out * (1 + 1e-6)
