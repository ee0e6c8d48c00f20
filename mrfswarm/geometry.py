"""Exact, vectorized distances between points, segments and axis-aligned boxes, in d dimensions.

All functions broadcast over leading axes; points and segment ends are (..., d) arrays,
d = 2 (squares) or 3 (cubes), by the same lines (:func:`polygon_box_distance` is planar).
"""

from __future__ import annotations

from functools import reduce
from itertools import product

import numpy as np

_EPS = 1e-12


def norm(v: np.ndarray) -> np.ndarray:
    """Euclidean length over the last axis of (..., d) arrays, by ``np.hypot`` axis after axis.

    In the plane this is ``np.hypot(x, y)`` exactly (the planar code's values, bit for bit).
    """
    v = np.asarray(v)
    return reduce(np.hypot, (v[..., k] for k in range(v.shape[-1])))


def box_corners(half: float, ndim: int) -> np.ndarray:
    """(2^d, d) corner offsets of the box of half-width ``half`` (``-half`` first on every axis)."""
    return np.array(list(product((-half, half), repeat=ndim)), dtype=float)


def downwash_scale(ndim: int, downwash: float = 1.0) -> np.ndarray:
    """Per-axis factors (ndim,) that map positions into the downwash-scaled space.

    Two robots are apart when ``|| (p - q) * downwash_scale(d, c) || >= 2 r``, that is
    sqrt(dx^2 + dy^2 + (dz / c)^2) >= 2 r in 3-D; in 2-D (or with c = 1) the factors are all 1,
    so every distance in the scaled space is the plain Euclidean one.
    """
    if ndim not in (2, 3):
        raise ValueError(f"downwash_scale: ndim must be 2 or 3, got {ndim}")
    if not downwash >= 1.0 or not np.isfinite(downwash):
        raise ValueError(f"downwash_scale: downwash must be a finite number >= 1, got {downwash}")
    s = np.ones(ndim)
    if ndim == 3:
        s[2] = 1.0 / downwash
    return s


def point_segment_distance(x: np.ndarray, p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Distance from point x to segment pq."""
    d = q - p
    L2 = np.einsum("...k,...k->...", d, d)
    s = np.einsum("...k,...k->...", x - p, d) / np.where(L2 > _EPS, L2, 1.0)
    s = np.clip(np.where(L2 > _EPS, s, 0.0), 0.0, 1.0)
    r = p + s[..., None] * d - x
    return norm(r)


def edge_gap(points: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    """Distance (cells) from each point (..., d), in cell coordinates, to the edge of a grid of ``shape``: the map
    spans [-0.5, S - 0.5] on each axis (floor and ceiling included), off it counts as a wall; 0 outside it."""
    pts = np.asarray(points, dtype=float)
    size = np.asarray(shape, dtype=float)
    gap = np.minimum(pts + 0.5, size - 0.5 - pts).min(axis=-1)
    return np.maximum(gap, 0.0)


def point_box_distance(x: np.ndarray, center: np.ndarray, half: float = 0.5) -> np.ndarray:
    """Distance from point x to the closed box (square, cube) of half-width ``half`` around ``center``."""
    g = np.maximum(0.0, np.abs(x - center) - half)
    return norm(g)


def _segment_hits_box(p: np.ndarray, q: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Liang–Barsky slab test, vectorized: does segment pq meet box [lo, hi]?"""
    d = q - p
    t0 = np.zeros(np.broadcast_shapes(p.shape[:-1], lo.shape[:-1]))
    t1 = np.ones_like(t0)
    hit = np.ones_like(t0, dtype=bool)
    for k in range(d.shape[-1]):
        dk = d[..., k]
        flat = np.abs(dk) < _EPS
        safe = np.where(flat, 1.0, dk)
        a = (lo[..., k] - p[..., k]) / safe
        b = (hi[..., k] - p[..., k]) / safe
        t0 = np.where(flat, t0, np.maximum(t0, np.minimum(a, b)))
        t1 = np.where(flat, t1, np.minimum(t1, np.maximum(a, b)))
        outside = flat & ((p[..., k] < lo[..., k]) | (p[..., k] > hi[..., k]))
        hit &= ~outside
    return hit & (t0 <= t1)


def segment_box_distance(p: np.ndarray, q: np.ndarray, center: np.ndarray, half: float = 0.5) -> np.ndarray:
    """Distance between segment pq and the closed box of half-width ``half`` at ``center`` (a square or a cube).

    Zero when they meet. Otherwise, in the plane, the minimum is attained at an end of
    the segment or at a corner of the square (both are convex polygons). In space the
    closest points may also be a point inside the segment and a point inside an edge of
    the cube, so the distance to each of the cube's 12 edges (segment-segment) is taken
    too (which covers the corners, the edges' ends): the minimum over the box is attained
    on its boundary; where the closest box point lies inside a face, the segment there is
    parallel to the face or ends, so sliding along it reaches an end or a face edge at
    the same distance.
    """
    p, q, center = np.asarray(p, float), np.asarray(q, float), np.asarray(center, float)
    ndim = p.shape[-1]
    lo, hi = center - half, center + half
    hit = _segment_hits_box(p, q, lo, hi)
    best = np.minimum(point_box_distance(p, center, half), point_box_distance(q, center, half))
    if ndim == 2:
        for c in box_corners(half, ndim):
            best = np.minimum(best, point_segment_distance(center + c, p, q))
    else:  # every corner is an end of an edge: the edges cover the corners
        a, b = _cube_edges(half)  # (12, 3) each
        shape = (12,) + (1,) * (np.ndim(best)) + (3,)
        d = segment_segment_distance(p, q, center + a.reshape(shape), center + b.reshape(shape))
        best = np.minimum(best, d.min(axis=0))
    return np.where(hit, 0.0, best)


def _cube_edges(half: float) -> tuple[np.ndarray, np.ndarray]:
    """The 12 edges of the cube of half-width ``half`` at the origin: their ends, (12, 3) and (12, 3)."""
    corners = box_corners(half, 3)
    pairs = [(i, j) for i in range(8) for j in range(i + 1, 8) if np.count_nonzero(corners[i] != corners[j]) == 1]
    return corners[[i for i, _ in pairs]], corners[[j for _, j in pairs]]


def segment_segment_distance(p1: np.ndarray, q1: np.ndarray, p2: np.ndarray, q2: np.ndarray) -> np.ndarray:
    """Distance between segments p1q1 and p2q2 in d dimensions (zero when they cross or touch).

    The squared distance f(s, t) = |p1 + s u - p2 - t v|^2 is convex on [0, 1]^2, so its
    minimum lies either on the square's boundary (an end of one segment against the
    other segment: four point-segment distances) or at the interior stationary point,
    the closest points of the two lines, when that exists (the lines not parallel) and
    lies inside both segments (in the plane: where the segments cross, at distance zero
    up to rounding, ~1e-16).
    """
    p1, q1, p2, q2 = (np.asarray(a, float) for a in (p1, q1, p2, q2))
    best = np.minimum.reduce([
        point_segment_distance(p1, p2, q2),
        point_segment_distance(q1, p2, q2),
        point_segment_distance(p2, p1, q1),
        point_segment_distance(q2, p1, q1),
    ])
    u, v, w = q1 - p1, q2 - p2, p1 - p2
    a = np.einsum("...k,...k->...", u, u)
    b = np.einsum("...k,...k->...", u, v)
    c = np.einsum("...k,...k->...", v, v)
    d = np.einsum("...k,...k->...", u, w)
    e = np.einsum("...k,...k->...", v, w)
    den = a * c - b * b
    ok = den > _EPS * np.maximum(a * c, _EPS)
    safe = np.where(ok, den, 1.0)
    s = (b * e - c * d) / safe
    t = (a * e - b * d) / safe
    inside = ok & (s > 0) & (s < 1) & (t > 0) & (t < 1)
    gap = w + s[..., None] * u - t[..., None] * v
    return np.where(inside, np.minimum(best, norm(gap)), best)


def segment_clear(free: np.ndarray, p: np.ndarray, q: np.ndarray, clearance: float = 0.5) -> bool:
    """True if every cell (voxel) closer than ``clearance`` to segment pq (cell units) is free and on the map."""
    p, q = np.asarray(p, float), np.asarray(q, float)
    r = int(np.ceil(clearance)) + 1
    lo = np.floor(np.minimum(p, q)).astype(int) - r
    hi = np.ceil(np.maximum(p, q)).astype(int) + r
    axes = np.meshgrid(*(np.arange(a, b + 1) for a, b in zip(lo, hi)), indexing="ij")
    cells = np.stack([x.ravel() for x in axes], axis=1)
    near = segment_box_distance(p, q, cells) < clearance - 1e-9
    cells = cells[near]
    inb = np.all((cells >= 0) & (cells < np.array(free.shape)), axis=1)
    if not inb.all():
        return False
    return bool(free[tuple(cells.T)].all())


def polygon_box_distance(polygon: np.ndarray, center: np.ndarray, half: float = 0.5) -> np.ndarray:
    """Distance between convex polygons and closed axis-aligned squares (zero when they meet).

    Parameters
    ----------
    polygon
        (..., V, 2) vertices of convex polygons, in order around each polygon.
    center
        (..., 2) square centres (broadcast against ``polygon[..., 0, :]``).
    half
        Half side of the squares.

    Notes
    -----
    They meet unless a separating axis exists among the coordinate axes and the polygon's
    edge normals (the separating axis theorem); apart, the distance between two convex
    polygons is attained at a vertex of one and an edge of the other.
    """
    poly = np.asarray(polygon, dtype=float)
    center = np.asarray(center, dtype=float)
    edges = np.roll(poly, -1, axis=-2) - poly  # (..., V, 2)
    normals = np.stack([-edges[..., 1], edges[..., 0]], axis=-1)
    axes = np.concatenate([np.broadcast_to(np.eye(2), poly.shape[:-2] + (2, 2)), normals], axis=-2)  # (..., A, 2)
    proj = np.einsum("...ak,...vk->...av", axes, poly)  # (..., A, V)
    c = (axes * center[..., None, :]).sum(axis=-1)
    r = half * np.abs(axes).sum(axis=-1)
    separated = (proj.max(axis=-1) < c - r) | (proj.min(axis=-1) > c + r)
    meet = ~separated.any(axis=-1)
    best = point_box_distance(poly, center[..., None, :], half).min(axis=-1)
    for sx in (-half, half):
        for sy in (-half, half):
            corner = (center + np.array([sx, sy]))[..., None, :]
            best = np.minimum(best, point_segment_distance(corner, poly, poly + edges).min(axis=-1))
    return np.where(meet, 0.0, best)
