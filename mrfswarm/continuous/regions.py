"""Time-indexed safe regions derived from the discrete plan.

All robots share one time grid: discrete step j (cells :math:`x_i^j \\to x_i^{j+1}`) is
flown during :math:`[t_j, t_{j+1}]` by one polynomial piece per robot. Two kinds of
linear constraints per step make the flight safe for all t; both are feasible because
the discrete plan itself (each robot on its straight segment, all with one time law)
satisfies them.

Obstacles: one convex region per robot and step. The discrete stage only makes a move
whose segment keeps half a cell from every occupied cell (and, for a one-cell move, the
whole bounding box of its two cells is free). So:

- *box*: when every cell of the bounding box of :math:`x_i^j, x_i^{j+1}` is free (always
  for search orders n <= 5), the box is grown greedily, up to ``growth`` cells per side
  (fractions of a cell too), over free cells (as safe-flight-corridor planners do, Liu et al. 2017, "Planning
  dynamically feasible trajectories for quadrotors using safe flight corridors"), and
  shrunk by the robot radius r: any centre inside keeps the robot's disc off every
  occupied cell;
- *oriented rectangle* otherwise: around the segment, half-width :math:`h < 1/2 - r`
  (cells) across it and :math:`e = \\sqrt{(1/2 - r)^2 - h^2}` beyond its ends, so every
  point is within :math:`1/2 - r` of the segment, whose half-cell tube holds no occupied
  cell.

A region is stored as d slabs, ``lower <= axes @ p <= upper`` (``axes`` orthonormal
rows), so both kinds have the same shape.

In space (d = 3, voxels) the same lines hold one axis more: boxes grow over voxels along
x, y and z; an oriented box has the move's direction u and two unit vectors across it
(an orthonormal frame), half-width :math:`h/\\sqrt{2}` on both, so its farthest corner is
still :math:`\\sqrt{h^2 + e^2} = 1/2 - r` cells from the segment; its clearance from
voxels is measured exactly (:func:`box_cube_distance`).

Robots: relative safe corridors (Park, Kim, Jang & Kim, "Efficient multi-agent trajectory
planning with feasibility guarantee using relative Bernstein polynomial", ICRA 2020).
The discrete stage guarantees that for robots i, k the relative segment
:math:`d(s) = d_0 + s v` (:math:`d_0 = x_i^j - x_k^j`, :math:`v` the difference of their
moves) stays at least one cell from the origin. With :math:`y^*` its point closest to the
origin and :math:`n = y^*/|y^*|`, convexity gives :math:`n^\\top d(s) \\ge |y^*| \\ge 1` cell
for all s, so the half-plane :math:`n^\\top (p_i - p_k) \\ge d_{safe}` (``distance``,
:math:`\\le` one cell) contains the discrete relative motion with room to spare, and any
trajectories in it keep :math:`|p_i - p_k| \\ge d_{safe}`. Both robots' pieces share the
step's interval and basis, so the relative trajectory's control points are the
differences of theirs: the constraint is linear and exact for all t.

Why relative corridors rather than per-robot separating hyperplanes between swept
segments (Hönig et al. 2018): the relative half-plane exists for every pair the discrete
plan keeps apart, including robots that follow each other within a step (A: 0 -> 1 while
B: 1 -> 2, whose swept segments touch, so no hyperplane separates them without splitting
the step), and it does not tie either robot to a time law: two robots flying in tandem
at any speed profile keep their relative position. The price is coupling: robots that
interact in a window are one QP (see :func:`interaction_groups`); robots whose regions
stay ``distance`` apart need no constraint at all.

Only pairs whose regions come within ``distance`` of each other get a constraint
(bounding boxes, through a k-d tree per step: near-linear in the number of robots).

Downwash (3-D): two robots are apart when :math:`\\|S (p_i - p_k)\\| \\ge d_{safe}` with
:math:`S = \\mathrm{diag}(s)`, ``s = geometry.downwash_scale(3, c)`` (z divided by c). The
discrete plan keeps every pair at least one cell apart in that metric along the moves, so
the construction above, run on the scaled relative motion :math:`S d(s)`, gives a unit
n with :math:`n^\\top S (p_i - p_k) \\ge d_{safe}`: still linear in the positions, so the
proof for all t carries over; the row's vector in world coordinates is :math:`S n`
(:attr:`Separations.normal`). In the plane, or with c = 1, S is the identity.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from mrfswarm.errors import ScenarioError
from mrfswarm.geometry import polygon_box_distance
from mrfswarm.maps import OccupancyGrid
from mrfswarm.maps.obstacles import ObstacleIndex
from mrfswarm.trajectory.piece_stack import norms

#: Regions are shrunk by this much more than the robot radius (metres per metre of cell), so
#: that rounding of world coordinates never leaves a region a hair closer than the radius.
_REGION_EPS = 1e-9
#: Room taken from the half-width of oriented rectangles to give them length (cells).
_ORIENTED_SLACK = 0.05


@dataclass(frozen=True)
class Regions:
    """One convex region per robot and step: ``lower <= axes @ p <= upper`` (metres).

    Attributes
    ----------
    axes
        (T, N, d, d): rows are orthonormal vectors (the identity for boxes).
    lower, upper
        (T, N, d).
    oriented
        (T, N) bool: an oriented rectangle (box, in space) rather than an axis-aligned box.
    radius
        The robot radius (metres) the regions were shrunk by.
    """

    axes: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    oriented: np.ndarray
    radius: float

    @property
    def steps(self) -> int:
        return self.axes.shape[0]

    @property
    def robots(self) -> int:
        return self.axes.shape[1]

    @property
    def dim(self) -> int:
        return self.axes.shape[-1]

    def corners(self) -> np.ndarray:
        """(T, N, 2^d, d) corners, in Gray-code order (in the plane: in order around each region)."""
        d = self.dim
        gray = np.arange(2**d) ^ (np.arange(2**d) >> 1)
        upper = (gray[:, None] >> np.arange(d)[None, :]) & 1  # (2^d, d): corner v takes the upper slab on axis k
        s = np.where(upper.astype(bool), self.upper[..., None, :], self.lower[..., None, :])  # slab coordinates
        return np.einsum("...ka,...vk->...va", self.axes, s)  # axes orthonormal: p = axes^T s

    def bounding_boxes(self) -> tuple[np.ndarray, np.ndarray]:
        """(T, N, d) lower and upper corners of each region's axis-aligned bounding box."""
        c = self.corners()
        return c.min(axis=-2), c.max(axis=-2)

    def violation(self, points: np.ndarray) -> np.ndarray:
        """How far points lie outside their regions (0 inside).

        Parameters
        ----------
        points
            (T, N, K, d): K points per robot and step (e.g. control points).

        Returns
        -------
        numpy.ndarray
            (T, N): the largest slab violation (metres) over the K points.
        """
        # s[t, n, p, k] = axes[t, n, k] . points[t, n, p], as einsum("tnka,tnpa->tnpk") sums it (bit for bit),
        # written out: einsum took a quarter of certifying 1000 robots over 300 steps
        ax = self.axes[:, :, None, :, :]
        s = ax[..., 0] * points[..., None, 0] + ax[..., 1] * points[..., None, 1]
        for a in range(2, self.dim):
            s += ax[..., a] * points[..., None, a]
        out = np.maximum(self.lower[:, :, None, :] - s, s - self.upper[:, :, None, :])
        return np.maximum(out.max(axis=(-1, -2)), 0.0)

    def window(self, a: int, b: int, robots: np.ndarray | None = None) -> Regions:
        """The regions of steps a..b-1 (and of ``robots`` only, if given)."""
        sl = (slice(a, b),) if robots is None else (slice(a, b), robots)
        return Regions(self.axes[sl], self.lower[sl], self.upper[sl], self.oriented[sl], self.radius)


def build_regions(paths: np.ndarray, grid: OccupancyGrid, radius: float, growth: float = 0.5,
                  index: ObstacleIndex | None = None, scale: np.ndarray | None = None) -> Regions:
    """The obstacle-free region of every robot in every step of the discrete ``paths``.

    Parameters
    ----------
    paths
        (T + 1, N, d) integer cells (d = 2 or 3, the grid's).
    grid
        The occupancy grid.
    radius
        Robot radius (metres), below half a cell.
    growth
        Cells a box may grow beyond the bounding box of the step's two cells, per side
        (a fraction of a cell reaches into the next row of cells only if it is free).
    index
        The grid's obstacle index (built here if not given).
    scale
        (d,) the downwash factors (``geometry.downwash_scale``; default ones): the growth is
        measured in the scaled metric, ``growth * scale[k]`` cells along axis k (along z
        growth / c). Two robots stacked at the discrete minimum (2 voxels apart with c = 2,
        one scaled cell) then get regions as far apart as two neighbours in the plane, and
        need no corridor between them unless they move towards each other.

    Raises
    ------
    ScenarioError
        A radius of half a cell or more (no region would be left).
    """
    res = grid.resolution
    if not 0 < radius < 0.5 * res:
        raise ScenarioError(f"robot radius {radius:g} m must be in (0, half a cell = {0.5 * res:g} m)")
    index = index or ObstacleIndex(grid)
    paths = np.asarray(paths, dtype=np.int64)
    a, b = paths[:-1], paths[1:]
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    box = index.occupied_count(lo, hi) == 0
    lo, hi = lo.copy(), hi.copy()
    ext_lo, ext_hi = np.zeros(lo.shape), np.zeros(hi.shape)  # fractional growth (cells) past lo, hi
    d = paths.shape[-1]
    grow = growth * (np.ones(d) if scale is None else np.asarray(scale, dtype=float))  # cells per axis
    whole, frac = np.floor(grow).astype(int), grow - np.floor(grow)
    for rnd in range(int((whole + (frac > 0)).max())):
        for axis in range(d):
            if rnd > whole[axis] or (rnd == whole[axis] and not frac[axis] > 0):
                continue  # this axis has grown all it may
            amount = 1.0 if rnd < whole[axis] else float(frac[axis])
            for side in (-1, 1):
                s_lo, s_hi = lo.copy(), hi.copy()
                # a strip also spans the fractions grown on the other axes (none yet with equal growth per axis:
                # then fractions come last; with growth per axis a whole row may follow another axis' fraction)
                for other in range(d):
                    if other != axis:
                        s_lo[..., other] -= ext_lo[..., other] > 0
                        s_hi[..., other] += ext_hi[..., other] > 0
                if side < 0:
                    s_lo[..., axis] = s_hi[..., axis] = lo[..., axis] - 1
                else:
                    s_lo[..., axis] = s_hi[..., axis] = hi[..., axis] + 1
                ok = box & (index.occupied_count(s_lo, s_hi) == 0)
                if amount < 1.0:
                    (ext_lo if side < 0 else ext_hi)[..., axis] += amount * ok
                elif side < 0:
                    lo[..., axis] -= ok
                else:
                    hi[..., axis] += ok
    shrink = radius + _REGION_EPS * res
    origin = np.asarray(grid.origin)
    T, N = a.shape[:2]
    axes = np.broadcast_to(np.eye(d), (T, N, d, d)).copy()
    lower = origin + (lo - 0.5 - ext_lo) * res + shrink
    upper = origin + (hi + 0.5 + ext_hi) * res - shrink
    if not box.all():
        p = grid.cell_to_world(a[~box])
        q = grid.cell_to_world(b[~box])
        u = (q - p) / np.linalg.norm(q - p, axis=-1, keepdims=True)
        w = across(u)  # (n, d - 1, d)
        H = 0.5 * res - shrink
        h = H - min(_ORIENTED_SLACK * res, H / 5)
        e = np.sqrt(H**2 - h**2)
        h = h / np.sqrt(d - 1)  # d - 1 directions across: the farthest corner is sqrt(h^2 + e^2) = H out
        axes[~box] = np.concatenate([u[:, None], w], axis=1)
        wp = (w * p[:, None, :]).sum(-1)
        lower[~box] = np.concatenate([((u * p).sum(-1) - e)[:, None], wp - h], axis=-1)
        upper[~box] = np.concatenate([((u * q).sum(-1) + e)[:, None], wp + h], axis=-1)
    return Regions(axes, lower, upper, ~box, float(radius))


def across(u: np.ndarray) -> np.ndarray:
    """(n, d - 1, d) unit vectors across unit vectors ``u`` (n, d): with u, an orthonormal frame.

    In the plane u turned by +90 degrees; in space the coordinate axis least aligned with u
    made orthogonal to it, then the cross product.
    """
    if u.shape[-1] == 2:
        return np.stack([-u[:, 1], u[:, 0]], axis=-1)[:, None, :]
    k = np.argmin(np.abs(u), axis=-1)
    e = np.eye(3)[k]
    w1 = e - (u * e).sum(-1, keepdims=True) * u
    w1 /= np.linalg.norm(w1, axis=-1, keepdims=True)
    return np.stack([w1, np.cross(u, w1)], axis=1)


def region_clearance(regions: Regions, grid: OccupancyGrid, reach: float) -> np.ndarray:
    """Exact distance (metres) from each region to the nearest occupied cell or the map's edge.

    Only cells within ``reach`` of a region are looked at: the result is the exact distance
    where it is below ``reach``, and ``reach`` otherwise.

    Returns
    -------
    numpy.ndarray
        (T, N).
    """
    res = grid.resolution
    origin = np.asarray(grid.origin)
    blo, bhi = regions.bounding_boxes()
    c_lo = np.floor((blo - reach - origin) / res + 0.5).astype(np.int64)
    c_hi = np.floor((bhi + reach - origin) / res + 0.5).astype(np.int64)
    out = np.full(regions.axes.shape[:2], float(reach))
    index = ObstacleIndex(grid)
    near = index.occupied_count(c_lo, c_hi) > 0
    if not near.any():
        return out
    t_idx, n_idx = np.nonzero(near)
    span = (c_hi - c_lo)[near].max(axis=0) + 1
    d = regions.dim
    offs = np.stack([g.ravel() for g in np.meshgrid(*[np.arange(n) for n in span], indexing="ij")], axis=1)  # (K, d)
    corners = regions.corners()
    chunk = max(1, 200_000 // len(offs))
    for s in range(0, len(t_idx), chunk):
        ti, ni = t_idx[s:s + chunk], n_idx[s:s + chunk]
        cells = c_lo[ti, ni][:, None, :] + offs[None, :, :]  # (R, K, d)
        valid = (cells <= c_hi[ti, ni][:, None, :]).all(axis=-1) & index.is_occupied(cells)
        centers = origin + cells * res
        if d == 2:
            poly = np.broadcast_to(corners[ti, ni][:, None], cells.shape[:2] + (4, 2))
            dist = np.where(valid, polygon_box_distance(poly, centers, 0.5 * res), np.inf)
        else:  # only the occupied voxels; a box's distance is the gap axis by axis, an oriented box's the
            # exact box-cube distance (200 features of each pair)
            dist = np.full(valid.shape, np.inf)
            r, k = np.nonzero(valid)
            rt, rn, c = ti[r], ni[r], centers[r, k]
            lo, hi = regions.lower[rt, rn], regions.upper[rt, rn]
            val = norms(np.maximum(0.0, np.maximum(lo - c - 0.5 * res, c - 0.5 * res - hi)))
            o = regions.oriented[rt, rn]
            val[o] = box_cube_distance(regions.axes[rt[o], rn[o]], lo[o], hi[o], c[o], 0.5 * res)
            dist[r, k] = val
        out[ti, ni] = np.minimum(out[ti, ni], dist.min(axis=1))
    return out


def _segment_distance(p1: np.ndarray, q1: np.ndarray, p2: np.ndarray, q2: np.ndarray) -> np.ndarray:
    """Distance between segments p1q1 and p2q2 (..., d) in any dimension, either possibly a point
    (the clamped closest points of Ericson, "Real-Time Collision Detection", 5.1.9)."""
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a, e = (d1 * d1).sum(-1), (d2 * d2).sum(-1)
    b, c, f = (d1 * d2).sum(-1), (d1 * r).sum(-1), (d2 * r).sum(-1)
    tiny = 1e-300
    pa, pe = a > 1e-24, e > 1e-24  # not a point
    denom = a * e - b * b
    s = np.where(denom > 1e-12 * a * e, np.clip((b * f - c * e) / np.maximum(denom, tiny), 0.0, 1.0), 0.0)
    t = np.where(pe, (b * s + f) / np.where(pe, e, 1.0), 0.0)
    tc = np.clip(t, 0.0, 1.0)
    s = np.where((t != tc) | ~pe, np.clip((b * tc - c) / np.where(pa, a, 1.0), 0.0, 1.0), s)
    s = np.where(pa, s, 0.0)
    tc = np.where(pa | ~pe, tc, np.clip(f / np.where(pe, e, 1.0), 0.0, 1.0))
    return norms(p1 + s[..., None] * d1 - p2 - tc[..., None] * d2)


def box_cube_distance(axes: np.ndarray, lower: np.ndarray, upper: np.ndarray, center: np.ndarray,
                      half: float) -> np.ndarray:
    """Exact distance between boxes ``lower <= axes @ p <= upper`` and axis-aligned cubes (zero when they meet).

    Parameters
    ----------
    axes
        (..., d, d) orthonormal rows.
    lower, upper
        (..., d).
    center
        (..., d) cube centres.
    half
        Half side of the cubes.

    Notes
    -----
    They meet unless one of the box's axes, the coordinate axes or (in space) the cross
    products of one of each separates them (the separating axis theorem for two boxes).
    Apart, two convex polytopes are closest between a vertex of one and the other, or
    between an edge of each: the distance is the smallest of the corners' distances to
    the other box (exact, in its own frame) and the edges' distances to each other.
    """
    d = axes.shape[-1]
    gray = np.arange(2**d) ^ (np.arange(2**d) >> 1)
    up = ((gray[:, None] >> np.arange(d)[None, :]) & 1).astype(bool)  # (V, d)
    slab = np.where(up, upper[..., None, :], lower[..., None, :])
    box = np.einsum("...ka,...vk->...va", axes, slab)  # (..., V, d) corners
    cube = center[..., None, :] + np.where(up, half, -half)  # (V, d)
    # separating axes
    eye = np.broadcast_to(np.eye(d), axes.shape)
    cand = [axes, eye]
    if d == 3:
        cand.append(np.cross(axes[..., :, None, :], eye[..., None, :, :]).reshape(axes.shape[:-2] + (9, 3)))
    ax = np.concatenate(cand, axis=-2)  # (..., A, d)
    pb = np.einsum("...ak,...vk->...av", ax, box)
    pc = np.einsum("...ak,...vk->...av", ax, cube)
    separated = (pb.max(-1) < pc.min(-1)) | (pc.max(-1) < pb.min(-1))
    meet = ~separated.any(axis=-1)
    best = norms(np.maximum(0.0, np.abs(box - center[..., None, :]) - half)).min(axis=-1)  # box corners to the cube
    sc = np.einsum("...ka,...va->...vk", axes, cube)  # cube corners in the box's frame
    best = np.minimum(best, norms(np.maximum(0.0, np.maximum(lower[..., None, :] - sc, sc - upper[..., None, :])))
                      .min(axis=-1))
    # edges: corner pairs that differ on one axis (V d / 2 of each)
    ei, ej = np.nonzero((np.bitwise_count(gray[:, None] ^ gray[None, :]) == 1) & (gray[:, None] < gray[None, :]))
    bp, bq = box[..., ei, :], box[..., ej, :]  # (..., E, d)
    cp, cq = cube[..., ei, :], cube[..., ej, :]
    edges = _segment_distance(bp[..., :, None, :], bq[..., :, None, :], cp[..., None, :, :], cq[..., None, :, :])
    best = np.minimum(best, edges.min(axis=(-1, -2)))
    return np.where(meet, 0.0, best)


@dataclass(frozen=True)
class Separations:
    """Relative safe corridors: ``normal . (p_first - p_second) >= distance`` during ``step``.

    ``normal`` is :math:`S n` for a unit n of the downwash-scaled space (``S`` =
    ``diag(downwash_scale)``, the identity in the plane): the row is
    :math:`n^\\top S (p_i - p_k) \\ge d_{safe}`.

    Attributes
    ----------
    step, first, second
        (P,) step index and the two robots (first < second).
    normal
        (P, d) the rows' vectors in world coordinates: unit normals scaled by the downwash
        factors (unit vectors in the plane and with c = 1).
    room
        (P,) how far the discrete relative motion stays inside the half-space (scaled
        metres): ``min_s normal . d(s) - distance``.
    distance
        The safety distance (metres).
    """

    step: np.ndarray
    first: np.ndarray
    second: np.ndarray
    normal: np.ndarray
    room: np.ndarray
    distance: float

    def __len__(self) -> int:
        return len(self.step)

    def select(self, mask: np.ndarray) -> Separations:
        """The constraints where ``mask`` is True."""
        return Separations(self.step[mask], self.first[mask], self.second[mask], self.normal[mask],
                           self.room[mask], self.distance)


def near_pairs(lo: np.ndarray, hi: np.ndarray, gap: float) -> np.ndarray:
    """Pairs (i < k) of axis-aligned boxes ``lo..hi`` (N, d) closer than ``gap`` (exact, via a k-d tree).

    Returns
    -------
    numpy.ndarray
        (P, 2) int.
    """
    if len(lo) < 2:
        return np.zeros((0, 2), dtype=np.int64)
    centre, half = (lo + hi) / 2, (hi - lo) / 2
    reach = 2 * float(norms(half).max()) + gap
    pairs = cKDTree(centre).query_pairs(reach, output_type="ndarray")
    if len(pairs) == 0:
        return np.zeros((0, 2), dtype=np.int64)
    g = np.maximum(0.0, np.abs(centre[pairs[:, 0]] - centre[pairs[:, 1]]) - half[pairs[:, 0]] - half[pairs[:, 1]])
    return pairs[norms(g) < gap]


def separations(positions: np.ndarray, regions: Regions, distance: float,
                scale: np.ndarray | None = None) -> Separations:
    """A relative safe corridor for every pair of robots whose regions come within ``distance``.

    Parameters
    ----------
    positions
        (T + 1, N, d) discrete positions in metres (cell centres).
    regions
        The robots' regions for the T steps.
    distance
        The safety distance (metres, in the scaled metric).
    scale
        (d,) the downwash factors (``geometry.downwash_scale``; default ones): pairs, their
        distance and their half-spaces are those of the scaled space.

    Raises
    ------
    ScenarioError
        Two robots whose discrete relative motion comes within ``distance``: the discrete
        plan breaks its own invariant.
    """
    S = np.ones(positions.shape[-1]) if scale is None else np.asarray(scale, dtype=float)
    blo, bhi = regions.bounding_boxes()
    blo, bhi = blo * S, bhi * S  # the scaled boxes (S > 0): the bounding boxes of the scaled regions
    none = np.zeros(0, dtype=np.int64)  # with no steps (the swarm starts at the goal) there are no pairs
    steps, firsts, seconds = [none], [none], [none]
    for j in range(regions.steps):
        p = near_pairs(blo[j], bhi[j], distance)
        steps.append(np.full(len(p), j))
        firsts.append(p[:, 0])
        seconds.append(p[:, 1])
    step = np.concatenate(steps).astype(np.int64)
    i, k = np.concatenate(firsts).astype(np.int64), np.concatenate(seconds).astype(np.int64)
    d0 = (positions[step, i] - positions[step, k]) * S
    v = ((positions[step + 1, i] - positions[step, i]) - (positions[step + 1, k] - positions[step, k])) * S
    vv = (v * v).sum(-1)
    s = np.clip(-(d0 * v).sum(-1) / np.where(vv > 0, vv, 1.0), 0.0, 1.0)
    y = d0 + s[:, None] * v
    ny = np.linalg.norm(y, axis=-1)
    bad = ny < distance
    if bad.any():
        q = int(np.argmax(bad))
        raise ScenarioError(f"robots {i[q]} and {k[q]} come {ny[q]:.3f} m apart in discrete step {step[q]}, "
                            f"closer than the safety distance {distance:g} m"
                            + ("" if np.all(S == 1) else " (downwash-scaled metric)"))
    return Separations(step, i, k, y / ny[:, None] * S, ny - distance, float(distance))


def interaction_groups(n_robots: int, seps: Separations) -> list[np.ndarray]:
    """Robots linked by any of ``seps``, as connected components (sorted robot indices each)."""
    if len(seps) == 0:
        return [np.array([i]) for i in range(n_robots)]
    adj = coo_matrix((np.ones(len(seps)), (seps.first, seps.second)), shape=(n_robots, n_robots))
    n, labels = connected_components(adj, directed=False)
    order = np.argsort(labels, kind="stable")
    return np.split(order, np.cumsum(np.bincount(labels, minlength=n))[:-1])


def arrival_holds(paths: np.ndarray, settle: int) -> np.ndarray:
    """(T, N) bool: the steps in which each robot is held still at its final cell.

    A robot whose discrete path makes no move after step k (it waits at its final cell to
    the end of the plan) is held from step k + ``settle`` on: the flight brakes to rest
    within the ``settle`` steps after its last move and stays there. Without it the window
    problems let an arrived robot drift through its grown box while the swarm arrives
    (minimum snap turns its arrival speed into a long overshoot and back, with a near-stop
    at every turn: 11 of the 18 stops of a 40-robot clutter flight). A robot that never
    moves is held from step ``settle``. The window loop applies the holds
    (:func:`hold_regions`) where its pieces and start states allow them.
    """
    paths = np.asarray(paths)
    T = len(paths) - 1
    moved = np.any(paths[1:] != paths[:-1], axis=-1)  # (T, N)
    arrived = np.where(moved.any(axis=0), T - np.argmax(moved[::-1], axis=0), 0) if T else np.zeros(paths.shape[1])
    return np.arange(T)[:, None] >= arrived[None, :] + settle


def hold_regions(regions: Regions, held: np.ndarray, centres: np.ndarray, half: float) -> Regions:
    """``regions`` with the boxes of the ``held`` (T, N) steps shrunk to half-width ``half`` (metres) around
    ``centres`` (T, N, d), the cells' centres.

    The held box lies inside the grown one (both around the cell) and holds the discrete
    plan (at rest at the cell); a ``half`` below the rows' tightening plus
    :data:`~mrfswarm.continuous.formulation.HOLD_WIDTH` makes the window problem's rows
    equalities at the centre.
    """
    if not held.any():
        return regions
    if regions.oriented[held].any():  # a wait's region is always a box
        raise AssertionError("a held step has an oriented region")
    lower, upper = regions.lower.copy(), regions.upper.copy()
    lower[held] = np.maximum(lower[held], centres[held] - half)
    upper[held] = np.minimum(upper[held], centres[held] + half)
    return Regions(regions.axes, lower, upper, regions.oriented, regions.radius)
