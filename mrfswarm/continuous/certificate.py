"""The certificate: what the continuous stage's safety proof rests on, checked exactly.

The proof (see :mod:`mrfswarm.continuous.regions`): all robots fly one polynomial piece
per discrete step on one time grid (a piece spanning several steps is split at them
first: :mod:`mrfswarm.continuous.merge_pieces`); a piece lies in the convex hull of its
Bernstein control points, and its derivatives in the hulls of theirs. So the flight is
safe for all t when

1. every region keeps at least the robot radius from every occupied cell and from the
   map's edge (:func:`~mrfswarm.continuous.regions.region_clearance`, exact; checked
   once per plan);
2. every position control point of robot i's piece in step j lies in its region
   (clearance >= radius for all t);
3. for every two robots whose pieces in a step come near each other, the convex hull
   of their *relative* control points (the differences, since both pieces share the
   step's interval and basis) stays at least the safety distance from the origin
   (separation >= safety distance for all t in the step);
4. every velocity, acceleration and jerk control point (of each quarter of a piece) is
   within its limit.

Check 3 does not use the planner's separating half-planes: it finds the pairs to look at
itself (control-point bounding boxes within the safety distance, through a k-d tree)
and computes the hull's distance from the origin exactly (the origin is outside a planar
hull iff the points' directions leave an angular gap wider than pi; the distance is then
the smallest distance to a segment between two of the points). Each check costs a fixed
amount per piece or near pair, so certifying is near-linear in the number of robots.
Dense sampling remains the independent check (:mod:`mrfswarm.continuous.sampled_check`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mrfswarm.continuous.formulation import LIMIT_PARTS
from mrfswarm.continuous.merge_pieces import step_pieces
from mrfswarm.continuous.regions import Regions, near_pairs
from mrfswarm.geometry import point_segment_distance
from mrfswarm.trajectory.bernstein import control_point_matrix
from mrfswarm.trajectory.piece_stack import (
    PIECE_CHUNK,
    map_coefficients,
    map_coefficients_in_order,
    squared_norms,
    stacked_tau_coefficients,
)
from mrfswarm.trajectory.polynomial import PiecewisePolynomial


@dataclass(frozen=True)
class Certificate:
    """The outcome of :func:`certify`.

    Attributes
    ----------
    ok
        Every check passed.
    problems
        What failed, one line each (empty when ``ok``).
    separation_bound
        A proven lower bound on the separation of every two robots: the smallest
        relative-hull distance of the pairs that come near each other, or the safety
        distance if that is smaller (pairs not near are at least that far apart).
    region_violation
        Largest distance of a control point outside its region (0 when all are inside).
    limit_bounds
        Proven upper bounds on speed, acceleration and jerk (largest control-point norms).
    near_pairs
        How many (pair, step) relative hulls were checked.
    """

    ok: bool
    problems: list[str] = field(default_factory=list)
    separation_bound: float = 0.0
    region_violation: float = 0.0
    limit_bounds: tuple[float, float, float] = (0.0, 0.0, 0.0)
    near_pairs: int = 0


def hull_distance_from_origin(points: np.ndarray) -> np.ndarray:
    """Exact distance from the origin to the convex hull of each set of planar points.

    Parameters
    ----------
    points
        (P, K, 2).

    Returns
    -------
    numpy.ndarray
        (P,): 0 when the origin is in a hull (or on its boundary).
    """
    K = points.shape[1]
    ang = np.sort(np.arctan2(points[..., 1], points[..., 0]), axis=1)
    gaps = np.concatenate([np.diff(ang, axis=1), (2 * np.pi - (ang[:, -1] - ang[:, 0]))[:, None]], axis=1)
    outside = gaps.max(axis=1) > np.pi
    i, j = np.triu_indices(K)  # every segment between two points (and every point itself)
    d = point_segment_distance(np.zeros(2), points[:, i], points[:, j]).min(axis=1)
    return np.where(outside, d, 0.0)


def certify_pieces(cps: list[np.ndarray], regions: Regions, distance: float,
                   limits: tuple[float, float, float]) -> Certificate:
    """Certify pieces given by their control points.

    Parameters
    ----------
    cps
        ``[P, V, A, J]``: (N, M, K_r, 2) control points of position and of its first three
        derivatives, robot i's piece j flown during step j of ``regions``.
    regions
        Regions of the same M steps and N robots.
    distance
        Safety distance (metres).
    limits
        (v_max, a_max, j_max).
    """
    norms = [np.linalg.norm(cps[r], axis=-1).max(axis=-1) for r in (1, 2, 3)]
    return _certify(cps[0], norms, regions, distance, limits)


def _certify(P: np.ndarray, limit_norms: list[np.ndarray], regions: Regions, distance: float,
             limits: tuple[float, float, float]) -> Certificate:
    """:func:`certify_pieces` from the position control points (N, M, K, 2) and, per limit,
    the (N, M) largest control-point norm of each piece."""
    M = P.shape[1]
    problems = []
    viol = regions.violation(P.transpose(1, 0, 2, 3))  # (M, N)
    worst = float(viol.max(initial=0.0))
    if worst > 0:
        j, i = (int(v) for v in np.unravel_index(int(np.argmax(viol)), viol.shape))
        problems.append(f"robot {i} leaves its region in step {j} by {worst:.3g} m")
    bounds = []
    for norms, lim, name in zip(limit_norms, limits, ("speed", "acceleration", "jerk")):
        top = float(norms.max(initial=0.0))
        bounds.append(top)
        if top > lim:
            i, j = (int(v) for v in np.unravel_index(int(np.argmax(norms)), norms.shape))
            problems.append(f"robot {i}'s {name} control points reach {top:.4g} > {lim:g} in step {j}")
    lo, hi = P.min(axis=2), P.max(axis=2)  # (N, M, 2)
    sep, checked = np.inf, 0
    for j in range(M):
        pairs = near_pairs(lo[:, j], hi[:, j], distance)
        if len(pairs) == 0:
            continue
        checked += len(pairs)
        d = hull_distance_from_origin(P[pairs[:, 0], j] - P[pairs[:, 1], j])
        k = int(np.argmin(d))
        if d[k] < sep:
            sep = float(d[k])
        if d[k] < distance:
            problems.append(f"robots {pairs[k, 0]} and {pairs[k, 1]} are not proven apart in step {j}: "
                            f"their relative control points come {d[k]:.4f} m from the origin "
                            f"(safety distance {distance:g} m)")
    return Certificate(not problems, problems, min(sep, distance), worst, (bounds[0], bounds[1], bounds[2]), checked)


def control_point_stack(trajectories: list[PiecewisePolynomial]) -> list[np.ndarray]:
    """[P, V, A, J] control points (N, M, K_r, 2) of trajectories that share their knots."""
    N, T = len(trajectories), trajectories[0].durations
    c = stacked_tau_coefficients(trajectories)  # (K, N M, 2)
    return [_robot_major(map_coefficients_in_order(control_point_matrix(len(c) - 1, r, 1 if r == 0 else LIMIT_PARTS), c),
                         N, len(T)) / T[None, :, None, None] ** r for r in range(4)]


def _robot_major(points: np.ndarray, N: int, M: int) -> np.ndarray:
    """Control points (K, N M, 2) of pieces robot after robot, as (N, M, K, 2)."""
    return np.ascontiguousarray(points.reshape(len(points), N, M, 2).transpose(1, 2, 0, 3))


def _limit_norms(c: np.ndarray, T: np.ndarray, order: int) -> np.ndarray:
    """(N M,) the largest norm of each piece's control points of the ``order``-th time derivative.

    ``c`` (K, N M, 2) are the tau-coefficients of pieces robot after robot, all on the
    durations ``T`` (M,). The norms come from matrix products (fast, but their last bits
    may differ from ``np.einsum``'s), taken
    :data:`~mrfswarm.trajectory.piece_stack.PIECE_CHUNK` pieces at a time so the control
    points of all pieces (384 MB for 1000 robots and 300 steps) never exist at once; the
    pieces within 1e-6 of the largest (rounding is some 1e-13) are then recomputed in the
    order of :func:`~mrfswarm.trajectory.bernstein.tau_control_points`, so the largest norm
    and where it is are those of :func:`control_point_stack` exactly.
    """
    matrix = control_point_matrix(len(c) - 1, order, LIMIT_PARTS)
    Tr = T ** order
    M, out = len(T), np.empty(c.shape[1])
    for s in range(0, c.shape[1], PIECE_CHUNK):
        e = min(s + PIECE_CHUNK, c.shape[1])
        out[s:e] = squared_norms(map_coefficients(matrix, c[:, s:e])).max(axis=0)
    out = np.sqrt(out) / Tr[np.arange(len(out)) % M]  # sqrt is monotone: the largest norm
    top = np.flatnonzero(out >= out.max(initial=0.0) * (1 - 1e-6))
    cp = map_coefficients_in_order(matrix, c[:, top]) / Tr[top % M, None]
    out[top] = np.sqrt(squared_norms(cp).max(axis=0))
    return out


def certify(trajectories: list[PiecewisePolynomial], knot_times: np.ndarray, regions: Regions, distance: float,
            limits: tuple[float, float, float]) -> Certificate:
    """Certify whole flights on the common time grid ``knot_times`` (the steps').

    A piece may span several steps (:mod:`mrfswarm.continuous.merge_pieces`): every
    trajectory's knots must be step times (to 1e-9 s), and its pieces are split at the
    steps (the restrictions are linear in the coefficients: the subdivided control
    points), so each step is certified exactly as a piece of its own. With one piece per
    step the result is that of ``certify_pieces(control_point_stack(trajectories), ...)``,
    without the limits' control points of all pieces at once (see :func:`_limit_norms`).
    """
    split = step_pieces(trajectories, knot_times)
    if isinstance(split, str):
        return Certificate(False, [split])
    trajectories = split
    N, T = len(trajectories), trajectories[0].durations
    c = stacked_tau_coefficients(trajectories)  # (K, N M, 2)
    P = _robot_major(map_coefficients_in_order(control_point_matrix(len(c) - 1), c), N, len(T))
    norms = [_limit_norms(c, T, r).reshape(N, len(T)) for r in (1, 2, 3)]
    return _certify(P, norms, regions, distance, limits)
