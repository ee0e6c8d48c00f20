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

A region is stored as two slabs, ``lower <= axes @ p <= upper`` (``axes`` orthonormal
rows), so both kinds have the same shape.

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
        (T, N, 2, 2): rows are unit vectors (the identity for boxes).
    lower, upper
        (T, N, 2).
    oriented
        (T, N) bool: an oriented rectangle rather than a box.
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

    def corners(self) -> np.ndarray:
        """(T, N, 4, 2) corners in order around each region."""
        s = np.stack([np.stack([self.lower[..., 0], self.lower[..., 1]], -1),
                      np.stack([self.upper[..., 0], self.lower[..., 1]], -1),
                      np.stack([self.upper[..., 0], self.upper[..., 1]], -1),
                      np.stack([self.lower[..., 0], self.upper[..., 1]], -1)], axis=-2)  # slab coordinates
        return np.einsum("...ka,...vk->...va", self.axes, s)  # axes orthonormal: p = axes^T s

    def bounding_boxes(self) -> tuple[np.ndarray, np.ndarray]:
        """(T, N, 2) lower and upper corners of each region's axis-aligned bounding box."""
        c = self.corners()
        return c.min(axis=-2), c.max(axis=-2)

    def violation(self, points: np.ndarray) -> np.ndarray:
        """How far points lie outside their regions (0 inside).

        Parameters
        ----------
        points
            (T, N, K, 2): K points per robot and step (e.g. control points).

        Returns
        -------
        numpy.ndarray
            (T, N): the largest slab violation (metres) over the K points.
        """
        # s[t, n, p, k] = axes[t, n, k] . points[t, n, p], as einsum("tnka,tnpa->tnpk") sums it (bit for bit),
        # written out: einsum took a quarter of certifying 1000 robots over 300 steps
        ax = self.axes[:, :, None, :, :]
        s = ax[..., 0] * points[..., None, 0] + ax[..., 1] * points[..., None, 1]
        out = np.maximum(self.lower[:, :, None, :] - s, s - self.upper[:, :, None, :])
        return np.maximum(out.max(axis=(-1, -2)), 0.0)

    def window(self, a: int, b: int, robots: np.ndarray | None = None) -> Regions:
        """The regions of steps a..b-1 (and of ``robots`` only, if given)."""
        sl = (slice(a, b),) if robots is None else (slice(a, b), robots)
        return Regions(self.axes[sl], self.lower[sl], self.upper[sl], self.oriented[sl], self.radius)


def build_regions(paths: np.ndarray, grid: OccupancyGrid, radius: float, growth: float = 0.5,
                  index: ObstacleIndex | None = None) -> Regions:
    """The obstacle-free region of every robot in every step of the discrete ``paths``.

    Parameters
    ----------
    paths
        (T + 1, N, 2) integer cells.
    grid
        The occupancy grid.
    radius
        Robot radius (metres), below half a cell.
    growth
        Cells a box may grow beyond the bounding box of the step's two cells, per side
        (a fraction of a cell reaches into the next row of cells only if it is free).
    index
        The grid's obstacle index (built here if not given).

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
    whole, frac = int(np.floor(growth)), float(growth - np.floor(growth))
    for rnd in range(whole + (frac > 0)):
        amount = 1.0 if rnd < whole else frac
        for axis in (0, 1):
            for side in (-1, 1):
                s_lo, s_hi = lo.copy(), hi.copy()
                if amount < 1.0:  # a fractional strip also spans the fractions grown on the other axis
                    s_lo[..., 1 - axis] -= ext_lo[..., 1 - axis] > 0
                    s_hi[..., 1 - axis] += ext_hi[..., 1 - axis] > 0
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
    axes = np.broadcast_to(np.eye(2), (T, N, 2, 2)).copy()
    lower = origin + (lo - 0.5 - ext_lo) * res + shrink
    upper = origin + (hi + 0.5 + ext_hi) * res - shrink
    if not box.all():
        p = grid.cell_to_world(a[~box])
        q = grid.cell_to_world(b[~box])
        u = (q - p) / np.linalg.norm(q - p, axis=-1, keepdims=True)
        w = np.stack([-u[:, 1], u[:, 0]], axis=-1)
        H = 0.5 * res - shrink
        h = H - min(_ORIENTED_SLACK * res, H / 5)
        e = np.sqrt(H**2 - h**2)
        axes[~box] = np.stack([u, w], axis=1)
        lower[~box] = np.stack([(u * p).sum(-1) - e, (w * p).sum(-1) - h], axis=-1)
        upper[~box] = np.stack([(u * q).sum(-1) + e, (w * p).sum(-1) + h], axis=-1)
    return Regions(axes, lower, upper, ~box, float(radius))


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
    ox, oy = np.meshgrid(np.arange(span[0]), np.arange(span[1]), indexing="ij")
    offs = np.stack([ox.ravel(), oy.ravel()], axis=1)  # (K, 2)
    corners = regions.corners()
    chunk = max(1, 200_000 // len(offs))
    for s in range(0, len(t_idx), chunk):
        ti, ni = t_idx[s:s + chunk], n_idx[s:s + chunk]
        cells = c_lo[ti, ni][:, None, :] + offs[None, :, :]  # (R, K, 2)
        valid = (cells <= c_hi[ti, ni][:, None, :]).all(axis=-1) & index.is_occupied(cells)
        centers = origin + cells * res
        poly = np.broadcast_to(corners[ti, ni][:, None], cells.shape[:2] + (4, 2))
        d = polygon_box_distance(poly, centers, 0.5 * res)
        d = np.where(valid, d, np.inf).min(axis=1)
        out[ti, ni] = np.minimum(out[ti, ni], d)
    return out


@dataclass(frozen=True)
class Separations:
    """Relative safe corridors: ``normal . (p_first - p_second) >= distance`` during ``step``.

    Attributes
    ----------
    step, first, second
        (P,) step index and the two robots (first < second).
    normal
        (P, 2) unit normals.
    room
        (P,) how far the discrete relative motion stays inside the half-plane (metres):
        ``min_s normal . d(s) - distance``.
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
    """Pairs (i < k) of axis-aligned boxes ``lo..hi`` (N, 2) closer than ``gap`` (exact, via a k-d tree).

    Returns
    -------
    numpy.ndarray
        (P, 2) int.
    """
    if len(lo) < 2:
        return np.zeros((0, 2), dtype=np.int64)
    centre, half = (lo + hi) / 2, (hi - lo) / 2
    reach = 2 * float(np.hypot(half[:, 0], half[:, 1]).max()) + gap
    pairs = cKDTree(centre).query_pairs(reach, output_type="ndarray")
    if len(pairs) == 0:
        return np.zeros((0, 2), dtype=np.int64)
    g = np.maximum(0.0, np.abs(centre[pairs[:, 0]] - centre[pairs[:, 1]]) - half[pairs[:, 0]] - half[pairs[:, 1]])
    return pairs[np.hypot(g[:, 0], g[:, 1]) < gap]


def separations(positions: np.ndarray, regions: Regions, distance: float) -> Separations:
    """A relative safe corridor for every pair of robots whose regions come within ``distance``.

    Parameters
    ----------
    positions
        (T + 1, N, 2) discrete positions in metres (cell centres).
    regions
        The robots' regions for the T steps.
    distance
        The safety distance (metres).

    Raises
    ------
    ScenarioError
        Two robots whose discrete relative motion comes within ``distance``: the discrete
        plan breaks its own invariant.
    """
    blo, bhi = regions.bounding_boxes()
    steps, firsts, seconds = [], [], []
    for j in range(regions.steps):
        p = near_pairs(blo[j], bhi[j], distance)
        steps.append(np.full(len(p), j))
        firsts.append(p[:, 0])
        seconds.append(p[:, 1])
    step = np.concatenate(steps).astype(np.int64)
    i, k = np.concatenate(firsts).astype(np.int64), np.concatenate(seconds).astype(np.int64)
    d0 = positions[step, i] - positions[step, k]
    v = (positions[step + 1, i] - positions[step, i]) - (positions[step + 1, k] - positions[step, k])
    vv = (v * v).sum(-1)
    s = np.clip(-(d0 * v).sum(-1) / np.where(vv > 0, vv, 1.0), 0.0, 1.0)
    y = d0 + s[:, None] * v
    ny = np.linalg.norm(y, axis=-1)
    bad = ny < distance
    if bad.any():
        q = int(np.argmax(bad))
        raise ScenarioError(f"robots {i[q]} and {k[q]} come {ny[q]:.3f} m apart in discrete step {step[q]}, "
                            f"closer than the safety distance {distance:g} m")
    return Separations(step, i, k, y / ny[:, None], ny - distance, float(distance))


def interaction_groups(n_robots: int, seps: Separations) -> list[np.ndarray]:
    """Robots linked by any of ``seps``, as connected components (sorted robot indices each)."""
    if len(seps) == 0:
        return [np.array([i]) for i in range(n_robots)]
    adj = coo_matrix((np.ones(len(seps)), (seps.first, seps.second)), shape=(n_robots, n_robots))
    n, labels = connected_components(adj, directed=False)
    order = np.argsort(labels, kind="stable")
    return np.split(order, np.cumsum(np.bincount(labels, minlength=n))[:-1])
