"""The whole-flight checks as they were before the piece stack (revision 0cf2173): the oracles.

One trajectory at a time and ``np.einsum`` over (..., K, dim) arrays, every near pair
bounded by its hull. ``tests/test_final_checks.py`` holds the fast versions to these:
the certificate and the control points bit for bit, the minimum separation and the
maxima to 1e-12 relative. ``certify_pieces`` and ``piece_extrema`` are the library's
(unchanged), so only what was rewritten is copied here.
"""

from __future__ import annotations

import numpy as np

from mrfswarm.continuous.certificate import Certificate, certify_pieces, hull_distance_from_origin
from mrfswarm.continuous.formulation import LIMIT_PARTS
from mrfswarm.continuous.regions import Regions, near_pairs
from mrfswarm.trajectory import PiecewisePolynomial
from mrfswarm.trajectory.bernstein import tau_control_points
from mrfswarm.trajectory.retiming import piece_extrema


def max_derivative_norm_all(trajectories: list[PiecewisePolynomial], order: int) -> float:
    c = np.concatenate([tr.derivative(order).tau_coefficients() for tr in trajectories])  # (P, n, dim)
    tau = np.linspace(0.0, 1.0, 9)
    sampled = np.linalg.norm(np.einsum("sk,pkd->psd", tau[:, None] ** np.arange(c.shape[1]), c), axis=-1).max()
    bound = np.linalg.norm(tau_control_points(c), axis=-1).max(axis=1)
    keep = bound >= sampled
    if not keep.any():
        return float(sampled)
    vals, _ = piece_extrema(c[keep])
    return float(max(sampled, vals.max()))


def control_point_stack(trajectories: list[PiecewisePolynomial]) -> list[np.ndarray]:
    c = np.stack([tr.tau_coefficients() for tr in trajectories])  # (N, M, D+1, 2)
    T = trajectories[0].durations
    return [tau_control_points(c, r, 1 if r == 0 else LIMIT_PARTS) / T[None, :, None, None] ** r for r in range(4)]


def certify(trajectories: list[PiecewisePolynomial], knot_times: np.ndarray, regions: Regions, distance: float,
            limits: tuple[float, float, float]) -> Certificate:
    for i, tr in enumerate(trajectories):
        if tr.pieces != len(knot_times) - 1 or not np.allclose(tr.knots, knot_times, rtol=0, atol=1e-9):
            return Certificate(False, [f"robot {i}'s pieces do not follow the common time grid"])
    return certify_pieces(control_point_stack(trajectories), regions, distance, limits)


def exact_min_separation(trajectories: list[PiecewisePolynomial], reach: float, block: int = 8) -> float:
    if len(trajectories) < 2:
        return float("inf")
    C = np.stack([tr.tau_coefficients() for tr in trajectories])  # (N, M, D+1, 2)
    P = tau_control_points(C, 0, 1)  # (N, M, D+1, 2) position control points
    lo, hi = P.min(axis=2), P.max(axis=2)
    span = float(np.ptp(P.reshape(-1, 2), axis=0).max()) + reach
    tau = np.linspace(0.0, 1.0, 9)
    V = tau[:, None] ** np.arange(C.shape[2])[None, :]  # (9, D+1)
    M = P.shape[1]
    while True:  # pairs left out are >= reach apart, so the minimum is exact once it is <= reach
        best = np.inf
        for j0 in range(0, M, block):
            rel_c, rel_p = [], []
            for j in range(j0, min(j0 + block, M)):
                pairs = near_pairs(lo[:, j], hi[:, j], reach)
                rel_c.append(C[pairs[:, 0], j] - C[pairs[:, 1], j])
                rel_p.append(P[pairs[:, 0], j] - P[pairs[:, 1], j])
            rc, rp = np.concatenate(rel_c), np.concatenate(rel_p)
            if not len(rc):
                continue
            best = min(best, float(np.linalg.norm(np.einsum("sk,pkd->psd", V, rc), axis=-1).min()))  # sampled: upper
            lower = hull_distance_from_origin(rp)  # control points: a lower bound per pair and step
            keep = lower <= best + 1e-9 * (1.0 + best)  # rounding: a bound attained at a piece's end
            if keep.any():
                vals, _ = piece_extrema(rc[keep], minimum=True)
                best = min(best, float(vals.min()))
        if best <= reach or reach > span:
            return best
        reach *= 4
