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

In space (d = 3) the same checks run on points of three coordinates. Separation is that of
the downwash-scaled space (``scale`` = ``geometry.downwash_scale(3, c)``: the relative
control points scaled axis by axis are the control points of the scaled relative
trajectory, since scaling is linear). The hull's distance is bounded from below by
:math:`\\min_k u^\\top p_k` for a unit u (every point of the hull is at least that far
along u); u points to the nearest of the candidate points of the hull (every point, the
nearest point of every segment and of every triangle of the points), which is the hull's
nearest point when the origin is outside: the bound is then the exact distance. Limits:
the Euclidean norms of the derivative control points over the three axes.
"""

from __future__ import annotations

import itertools
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
    norms,
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
        A proven lower bound on the separation of every two robots (downwash-scaled
        metric): the smallest relative-hull distance of the pairs that come near each
        other, or the safety distance if that is smaller (pairs not near are at least that
        far apart).
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
    """Exact distance from the origin to the convex hull of each set of points (planar or in space).

    Parameters
    ----------
    points
        (P, K, d), d = 2 or 3.

    Returns
    -------
    numpy.ndarray
        (P,): 0 when the origin is in a hull (or on its boundary). In space a proven lower
        bound, exact (to rounding) when the origin is outside (:func:`_hull_bound`).
    """
    if points.shape[-1] != 2:
        return _hull_bound(points)
    K = points.shape[1]
    ang = np.sort(np.arctan2(points[..., 1], points[..., 0]), axis=1)
    gaps = np.concatenate([np.diff(ang, axis=1), (2 * np.pi - (ang[:, -1] - ang[:, 0]))[:, None]], axis=1)
    outside = gaps.max(axis=1) > np.pi
    i, j = np.triu_indices(K)  # every segment between two points (and every point itself)
    d = point_segment_distance(np.zeros(2), points[:, i], points[:, j]).min(axis=1)
    return np.where(outside, d, 0.0)


def _hull_bound(points: np.ndarray) -> np.ndarray:
    """(P,) a lower bound on the distance from the origin to the hull of each (K, d) set of points.

    For any unit u, :math:`\\min_k u^\\top p_k` bounds the distance from below (when
    positive). u points to the nearest candidate: each point, the nearest point of each
    segment between two points, and the foot of the origin on the plane of each triangle of
    three points when it lies inside the triangle. With the origin outside, the hull's
    nearest point lies on a facet, a triangle of the points (or an edge or a point), so it
    is the nearest candidate and the bound is the distance itself; with the origin inside,
    the bound is 0.
    """
    P, K, _ = points.shape
    i, j = np.triu_indices(K, 1)
    a, ab = points[:, i], points[:, j] - points[:, i]  # (P, S, d)
    L2 = (ab * ab).sum(-1)
    s = np.clip(-(a * ab).sum(-1) / np.where(L2 > 0, L2, 1.0), 0.0, 1.0)
    cand = [points, a + s[..., None] * ab]
    if K >= 3 and points.shape[-1] == 3:
        t = np.array(list(itertools.combinations(range(K), 3)))
        A, B, C = points[:, t[:, 0]], points[:, t[:, 1]], points[:, t[:, 2]]
        e0, e1 = B - A, C - A
        n = np.cross(e0, e1)
        nn = (n * n).sum(-1)
        # slivers (sin^2 of their angle below 1e-12) are left to their edges, which come within 1e-6 of them:
        # the foot of a sliver's plane is rounding noise (the plane through a near-line turns freely about it)
        flat = nn <= 1e-12 * np.maximum((e0 * e0).sum(-1) * (e1 * e1).sum(-1), 1e-300)
        foot = n * ((n * A).sum(-1) / np.where(flat, 1.0, nn))[..., None]  # the origin's projection on the plane
        w = foot - A
        d00, d01, d11 = (e0 * e0).sum(-1), (e0 * e1).sum(-1), (e1 * e1).sum(-1)
        d20, d21 = (w * e0).sum(-1), (w * e1).sum(-1)
        den = np.where(flat, 1.0, nn)  # d00 d11 - d01^2 = |e0 x e1|^2, without the cancellation
        v, u = (d11 * d20 - d01 * d21) / den, (d00 * d21 - d01 * d20) / den
        inside = ~flat & (v >= 0) & (u >= 0) & (u + v <= 1)
        cand.append(np.where(inside[..., None], foot, points[:, :1]))  # else a point already a candidate
    # two directions, each a valid bound: the nearest candidate's, and the nearest point or segment's
    # (robust: clamped projections), in case rounding put a triangle's foot nearer than the hull is
    out = np.zeros(P)
    for c in (np.concatenate(cand, axis=1), np.concatenate(cand[:2], axis=1)):
        x = c[np.arange(P), np.argmin(norms(c), axis=1)]  # (P, d)
        nx = norms(x)
        u = x / np.where(nx > 0, nx, 1.0)[:, None]
        bound = (points * u[:, None, :]).sum(-1).min(axis=1)
        out = np.maximum(out, np.where(nx > 0, bound, 0.0))
    return out


def certify_pieces(cps: list[np.ndarray], regions: Regions, distance: float,
                   limits: tuple[float, float, float], scale: np.ndarray | None = None) -> Certificate:
    """Certify pieces given by their control points.

    Parameters
    ----------
    cps
        ``[P, V, A, J]``: (N, M, K_r, d) control points of position and of its first three
        derivatives, robot i's piece j flown during step j of ``regions``.
    regions
        Regions of the same M steps and N robots.
    distance
        Safety distance (metres, downwash-scaled metric).
    limits
        (v_max, a_max, j_max).
    scale
        (d,) downwash factors of the separation metric (default: ones).
    """
    top = [np.linalg.norm(cps[r], axis=-1).max(axis=-1) for r in (1, 2, 3)]
    return _certify(cps[0], top, regions, distance, limits, scale)


def _certify(P: np.ndarray, limit_norms: list[np.ndarray], regions: Regions, distance: float,
             limits: tuple[float, float, float], scale: np.ndarray | None = None) -> Certificate:
    """:func:`certify_pieces` from the position control points (N, M, K, d) and, per limit,
    the (N, M) largest control-point norm of each piece."""
    M = P.shape[1]
    problems = []
    viol = regions.violation(P.transpose(1, 0, 2, 3))  # (M, N)
    worst = float(viol.max(initial=0.0))
    if worst > 0:
        j, i = (int(v) for v in np.unravel_index(int(np.argmax(viol)), viol.shape))
        problems.append(f"robot {i} leaves its region in step {j} by {worst:.3g} m{_others(viol.max(axis=0) > 0)}")
    bounds = []
    for piece_top, lim, name in zip(limit_norms, limits, ("speed", "acceleration", "jerk")):
        top = float(piece_top.max(initial=0.0))
        bounds.append(top)
        if top > lim:
            i, j = (int(v) for v in np.unravel_index(int(np.argmax(piece_top)), piece_top.shape))
            problems.append(f"robot {i}'s {name} control points reach {top:.4g} > {lim:g} in step {j} (by {top - lim:.2g})"
                            f"{_others(piece_top.max(axis=1) > lim)}")
    S = P if scale is None or np.all(np.asarray(scale) == 1.0) else P * np.asarray(scale, dtype=float)
    lo, hi = S.min(axis=2), S.max(axis=2)  # (N, M, d), in the scaled space
    sep, checked = np.inf, 0
    for j in range(M):
        pairs = near_pairs(lo[:, j], hi[:, j], distance)
        if len(pairs) == 0:
            continue
        checked += len(pairs)
        d = hull_distance_from_origin(S[pairs[:, 0], j] - S[pairs[:, 1], j])
        k = int(np.argmin(d))
        if d[k] < sep:
            sep = float(d[k])
        if d[k] < distance:
            problems.append(f"robots {pairs[k, 0]} and {pairs[k, 1]} are not proven apart in step {j}: "
                            f"their relative control points come {d[k]:.4f} m from the origin "
                            f"(safety distance {distance:g} m)")
    return Certificate(not problems, problems, min(sep, distance), worst, (bounds[0], bounds[1], bounds[2]), checked)


def _others(over: np.ndarray) -> str:
    """", the worst of n robots over" when more robots than the one a problem names break its rule (a problem names
    the worst; a 3-D tour read one robot's jerk where all twelve were over)."""
    n = int(np.count_nonzero(over))
    return f", the worst of {n} robots over" if n > 1 else ""


def control_point_stack(trajectories: list[PiecewisePolynomial]) -> list[np.ndarray]:
    """[P, V, A, J] control points (N, M, K_r, d) of trajectories that share their knots."""
    N, T = len(trajectories), trajectories[0].durations
    c = stacked_tau_coefficients(trajectories)  # (K, N M, d)
    return [_robot_major(map_coefficients_in_order(control_point_matrix(len(c) - 1, r, 1 if r == 0 else LIMIT_PARTS), c),
                         N, len(T)) / T[None, :, None, None] ** r for r in range(4)]


def _robot_major(points: np.ndarray, N: int, M: int) -> np.ndarray:
    """Control points (K, N M, d) of pieces robot after robot, as (N, M, K, d)."""
    return np.ascontiguousarray(points.reshape(len(points), N, M, points.shape[-1]).transpose(1, 2, 0, 3))


def _limit_norms(c: np.ndarray, T: np.ndarray, order: int) -> np.ndarray:
    """(N M,) the largest norm of each piece's control points of the ``order``-th time derivative.

    ``c`` (K, N M, d) are the tau-coefficients of pieces robot after robot, all on the
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
            limits: tuple[float, float, float], scale: np.ndarray | None = None) -> Certificate:
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
    c = stacked_tau_coefficients(trajectories)  # (K, N M, d)
    P = _robot_major(map_coefficients_in_order(control_point_matrix(len(c) - 1), c), N, len(T))
    tops = [_limit_norms(c, T, r).reshape(N, len(T)) for r in (1, 2, 3)]
    return _certify(P, tops, regions, distance, limits, scale)
