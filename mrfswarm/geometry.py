"""Exact, vectorized planar distances between points, segments and axis-aligned squares.

All functions broadcast over leading axes; points and segment ends are (..., 2) arrays.
"""

from __future__ import annotations

import numpy as np

_EPS = 1e-12


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
    return np.hypot(r[..., 0], r[..., 1])


def point_box_distance(x: np.ndarray, center: np.ndarray, half: float = 0.5) -> np.ndarray:
    """Distance from point x to the closed square of half-width ``half`` around ``center``."""
    g = np.maximum(0.0, np.abs(x - center) - half)
    return np.hypot(g[..., 0], g[..., 1])


def _segment_hits_box(p: np.ndarray, q: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Liang–Barsky slab test, vectorized: does segment pq meet box [lo, hi]?"""
    d = q - p
    t0 = np.zeros(np.broadcast_shapes(p.shape[:-1], lo.shape[:-1]))
    t1 = np.ones_like(t0)
    hit = np.ones_like(t0, dtype=bool)
    for k in range(2):
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
    """Distance between segment pq and the closed square of half-width ``half`` at ``center``.

    Zero when they meet; otherwise the minimum is attained at an end of the segment or at
    a corner of the square (both are convex polygons).
    """
    p, q, center = np.asarray(p, float), np.asarray(q, float), np.asarray(center, float)
    lo, hi = center - half, center + half
    hit = _segment_hits_box(p, q, lo, hi)
    best = np.minimum(point_box_distance(p, center, half), point_box_distance(q, center, half))
    for sx in (-half, half):
        for sy in (-half, half):
            corner = center + np.array([sx, sy])
            best = np.minimum(best, point_segment_distance(corner, p, q))
    return np.where(hit, 0.0, best)


def segment_segment_distance(p1: np.ndarray, q1: np.ndarray, p2: np.ndarray, q2: np.ndarray) -> np.ndarray:
    """Distance between segments p1q1 and p2q2 (zero when they cross or touch)."""
    p1, q1, p2, q2 = (np.asarray(a, float) for a in (p1, q1, p2, q2))

    def cross(o, a, b):
        return (a[..., 0] - o[..., 0]) * (b[..., 1] - o[..., 1]) - (a[..., 1] - o[..., 1]) * (b[..., 0] - o[..., 0])

    d1, d2 = cross(p2, q2, p1), cross(p2, q2, q1)
    d3, d4 = cross(p1, q1, p2), cross(p1, q1, q2)
    proper = (((d1 > _EPS) & (d2 < -_EPS)) | ((d1 < -_EPS) & (d2 > _EPS))) & (
        ((d3 > _EPS) & (d4 < -_EPS)) | ((d3 < -_EPS) & (d4 > _EPS)))
    best = np.minimum.reduce([
        point_segment_distance(p1, p2, q2),
        point_segment_distance(q1, p2, q2),
        point_segment_distance(p2, p1, q1),
        point_segment_distance(q2, p1, q1),
    ])
    return np.where(proper, 0.0, best)


def segment_clear(free: np.ndarray, p: np.ndarray, q: np.ndarray, clearance: float = 0.5) -> bool:
    """True if every cell closer than ``clearance`` to segment pq (cell units) is free and on the map."""
    p, q = np.asarray(p, float), np.asarray(q, float)
    r = int(np.ceil(clearance)) + 1
    lo = np.floor(np.minimum(p, q)).astype(int) - r
    hi = np.ceil(np.maximum(p, q)).astype(int) + r
    xs, ys = np.meshgrid(np.arange(lo[0], hi[0] + 1), np.arange(lo[1], hi[1] + 1), indexing="ij")
    cells = np.stack([xs.ravel(), ys.ravel()], axis=1)
    near = segment_box_distance(p, q, cells) < clearance - 1e-9
    cells = cells[near]
    W, H = free.shape
    inb = (cells[:, 0] >= 0) & (cells[:, 0] < W) & (cells[:, 1] >= 0) & (cells[:, 1] < H)
    if not inb.all():
        return False
    return bool(free[cells[:, 0], cells[:, 1]].all())


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
