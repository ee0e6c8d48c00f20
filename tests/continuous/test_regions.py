"""Safe regions and relative safe corridors: valid by construction, checked against brute force."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mrfswarm.continuous.regions import (
    Regions,
    build_regions,
    interaction_groups,
    near_pairs,
    region_clearance,
    separations,
)
from mrfswarm.errors import ScenarioError
from mrfswarm.geometry import point_box_distance, polygon_box_distance
from mrfswarm.maps import OccupancyGrid
from mrfswarm.maps.obstacles import ObstacleIndex


def brute_region_clearance(regions: Regions, grid: OccupancyGrid, samples: int = 60) -> np.ndarray:
    """Distance from each region (sampled densely, boundary included) to every occupied square and the map's edge."""
    corners = regions.corners()
    u = np.linspace(0.0, 1.0, samples)
    a, b = np.meshgrid(u, u, indexing="ij")
    p0, p1, p3 = corners[..., 0, :], corners[..., 1, :], corners[..., 3, :]
    pts = p0[..., None, :] + a.ravel()[:, None] * (p1 - p0)[..., None, :] + b.ravel()[:, None] * (p3 - p0)[..., None, :]
    occ = grid.cell_to_world(np.argwhere(grid.occupied))
    out = np.full(regions.axes.shape[:2], np.inf)
    if len(occ):
        d = point_box_distance(pts[..., None, :], occ, grid.resolution / 2)
        out = d.min(axis=(-1, -2))
    x0, x1, y0, y1 = grid.extent
    edge = np.minimum.reduce([pts[..., 0] - x0, x1 - pts[..., 0], pts[..., 1] - y0, y1 - pts[..., 1]]).min(axis=-1)
    return np.minimum(out, edge)


@pytest.mark.parametrize("shape", [(9, 7), (6, 5, 4)])
def test_obstacle_index_counts_like_brute_force(shape):
    rng = np.random.default_rng(0)
    occ = rng.random(shape) < 0.3
    index = ObstacleIndex(OccupancyGrid.from_occupied(occ))
    d = len(shape)
    padded = np.ones((20,) * d, bool)  # the map with a wide margin of off-map (occupied) cells
    padded[tuple(slice(3, 3 + n) for n in shape)] = occ
    for _ in range(300):
        lo = rng.integers(-3, 10, d)
        hi = lo + rng.integers(-1, 5, d)
        want = padded[tuple(slice(a + 3, b + 4) for a, b in zip(lo, hi))].sum() if (hi >= lo).all() else 0
        assert index.occupied_count(lo, hi) == want
    many = rng.integers(-2, 8, (4, 5, d))  # vectorized over leading axes
    assert index.occupied_count(many, many + 1).shape == (4, 5)


def test_polygon_box_distance_matches_sampling():
    rng = np.random.default_rng(1)
    for _ in range(50):
        c = rng.normal(size=2) * 2
        ang = rng.uniform(0, np.pi)
        u, w = np.array([np.cos(ang), np.sin(ang)]), np.array([-np.sin(ang), np.cos(ang)])
        h = rng.uniform(0.1, 1.0, 2)
        poly = np.array([c - h[0] * u - h[1] * w, c + h[0] * u - h[1] * w, c + h[0] * u + h[1] * w,
                         c - h[0] * u + h[1] * w])
        box = rng.normal(size=2) * 2
        s = np.linspace(0, 1, 201)
        a, b = np.meshgrid(s, s)
        pts = poly[0] + a.ravel()[:, None] * (poly[1] - poly[0]) + b.ravel()[:, None] * (poly[3] - poly[0])
        sampled = point_box_distance(pts, box, 0.5).min()
        exact = float(polygon_box_distance(poly, box, 0.5))
        assert exact <= sampled + 1e-12 and sampled - exact < 0.02


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), res=st.sampled_from([0.5, 1.0, 2.0]), growth=st.sampled_from([0.0, 0.5, 1.0, 2.0]))
def test_regions_keep_the_radius_from_obstacles(seed, res, growth):
    """On random maps, every region of every (legal) move keeps the radius from obstacles and the map edge,
    and contains both ends of its move."""
    rng = np.random.default_rng(seed)
    occ = rng.random((12, 10)) < 0.25
    grid = OccupancyGrid.from_occupied(occ, resolution=res, origin=(rng.normal(), rng.normal()))
    free = np.argwhere(~occ)
    from mrfswarm.discrete.motion import moves_clear, stencil

    order = int(rng.choice([2, 5, 8]))
    start = free[rng.choice(len(free), size=min(6, len(free)), replace=False)]
    offs = stencil(order)
    idx = np.broadcast_to(np.arange(len(offs)), (len(start), len(offs)))
    ok = moves_clear(grid.free, start, idx, order)  # (N, S) legal moves by the discrete stage's rule
    pick = np.array([rng.choice(np.flatnonzero(row)) for row in ok])
    paths = np.stack([start, start + offs[pick]])[:, :, :]
    radius = 0.24 * res
    regions = build_regions(paths, grid, radius, growth)
    clr = region_clearance(regions, grid, 2 * radius)
    assert (clr >= radius).all()
    brute = brute_region_clearance(regions, grid)
    assert (np.minimum(brute, 2 * radius) >= clr - 1e-9).all()  # the exact value is below every sample
    ends = grid.cell_to_world(paths).transpose(1, 0, 2)[None]  # (1, N, 2 ends, 2)
    assert (regions.violation(ends) <= 1e-9).all()


def test_oriented_rectangles_for_long_moves_past_corners():
    """A (2, 2) move whose bounding box holds an obstacle gets an oriented rectangle that avoids it."""
    occ = np.zeros((5, 5), bool)
    occ[0, 2] = occ[2, 0] = True  # the corners of the box (0,0)-(2,2), outside the move's half-cell tube
    grid = OccupancyGrid.from_occupied(occ)
    paths = np.array([[[0, 0]], [[2, 2]]])
    regions = build_regions(paths, grid, 0.25, growth=1)
    assert regions.oriented[0, 0]
    assert region_clearance(regions, grid, 1.0)[0, 0] >= 0.25
    assert regions.violation(grid.cell_to_world(paths).transpose(1, 0, 2)[None])[0, 0] == 0.0


def test_a_move_through_a_wall_gives_an_invalid_region():
    """The guard behind it: a region is checked, not trusted. A move that cuts a corner fails the check."""
    occ = np.zeros((4, 4), bool)
    occ[1, 0] = True
    grid = OccupancyGrid.from_occupied(occ)
    paths = np.array([[[0, 0]], [[2, 1]]])  # passes 0.22 cell from the occupied cell (1, 0)
    regions = build_regions(paths, grid, 0.25, growth=0)
    assert region_clearance(regions, grid, 0.5)[0, 0] < 0.25


def test_radius_must_leave_room():
    grid = OccupancyGrid.from_occupied(np.zeros((3, 3), bool), resolution=0.5)
    with pytest.raises(ScenarioError, match="robot radius 0.25 m must be in"):
        build_regions(np.zeros((2, 1, 2), int), grid, 0.25)


def test_growth_makes_room_only_over_free_cells():
    occ = np.zeros((7, 7), bool)
    occ[:, 5] = True
    grid = OccupancyGrid.from_occupied(occ)
    paths = np.array([[[3, 3]], [[3, 3]]])
    r0 = build_regions(paths, grid, 0.25, growth=0)
    r1 = build_regions(paths, grid, 0.25, growth=1)
    r3 = build_regions(paths, grid, 0.25, growth=3)
    np.testing.assert_allclose(r0.lower[0, 0], [2.75, 2.75])
    np.testing.assert_allclose(r1.lower[0, 0], [1.75, 1.75])
    np.testing.assert_allclose(r1.upper[0, 0], [4.25, 4.25])
    np.testing.assert_allclose(r3.upper[0, 0], [6.25, 4.25])  # the wall at y = 5 stops it; x reaches the map edge


def test_followers_get_a_corridor_along_their_motion():
    """A: 0 -> 1 while B: 1 -> 2 in a one-cell corridor: swept segments touch, the relative corridor exists."""
    occ = np.ones((6, 3), bool)
    occ[:, 1] = False
    grid = OccupancyGrid.from_occupied(occ)
    paths = np.array([[[0, 1], [1, 1]], [[1, 1], [2, 1]]])
    X = grid.cell_to_world(paths)
    regions = build_regions(paths, grid, 0.25, growth=1)
    seps = separations(X, regions, 0.5)
    assert len(seps) == 1
    np.testing.assert_allclose(seps.normal[0], [-1.0, 0.0])  # p_A - p_B points along -x
    assert seps.room[0] == pytest.approx(0.5)


def test_relative_corridor_contains_the_discrete_relative_motion():
    rng = np.random.default_rng(3)
    grid = OccupancyGrid.from_occupied(np.zeros((30, 30), bool))
    for _ in range(20):
        a = rng.integers(5, 25, (2, 2))
        mv = rng.integers(-1, 2, (2, 2))
        paths = np.stack([a, a + mv])
        d0, v = paths[0, 0] - paths[0, 1], (paths[1, 0] - paths[0, 0]) - (paths[1, 1] - paths[0, 1])
        s = np.linspace(0, 1, 101)[:, None]
        if np.linalg.norm(d0 + s * v, axis=1).min() < 1:  # not a legal discrete step
            continue
        regions = build_regions(paths, grid, 0.25, growth=1)
        seps = separations(grid.cell_to_world(paths), regions, 0.5)
        for n in seps.normal:
            assert ((d0 + s * v) @ n).min() >= 1 - 1e-9


def test_a_discrete_plan_that_breaks_its_invariant_is_refused():
    grid = OccupancyGrid.from_occupied(np.zeros((6, 6), bool))
    paths = np.array([[[1, 1], [3, 1]], [[2, 1], [2, 1]]])  # both end up in cell (2, 1)... robot 0 moves into 1
    regions = build_regions(paths, grid, 0.25, growth=0)
    with pytest.raises(ScenarioError, match="robots 0 and 1 come 0.000 m apart in discrete step 0"):
        separations(grid.cell_to_world(paths), regions, 0.5)


def test_near_pairs_match_brute_force_including_the_boundary():
    rng = np.random.default_rng(4)
    lo = rng.integers(0, 20, (60, 2)).astype(float)
    hi = lo + rng.integers(0, 3, (60, 2))
    lo[1], hi[1] = hi[0] + [0.5, 0.0], hi[0] + [1.5, 1.0]  # exactly 0.5 apart: not closer than 0.5
    got = {tuple(p) for p in near_pairs(lo, hi, 0.5)}
    want = set()
    for i in range(60):
        for k in range(i + 1, 60):
            g = np.maximum(0, np.maximum(lo[i] - hi[k], lo[k] - hi[i]))
            if np.hypot(*g) < 0.5:
                want.add((i, k))
    assert got == want and (0, 1) not in got


def test_interaction_groups_are_connected_components():
    from mrfswarm.continuous.regions import Separations

    seps = Separations(np.zeros(3, int), np.array([0, 1, 4]), np.array([1, 2, 5]), np.ones((3, 2)), np.ones(3), 0.5)
    groups = interaction_groups(7, seps)
    assert sorted(map(tuple, groups)) == [(0, 1, 2), (3,), (4, 5), (6,)]


def test_separations_of_a_plan_without_steps_are_empty():
    X = np.array([[[0.5, 0.5], [2.5, 0.5]]])  # (T + 1 = 1, N = 2, d): no step
    grid = OccupancyGrid(np.zeros((4, 4), dtype=bool))
    seps = separations(X, build_regions(np.array([[[0, 0], [2, 0]]]), grid, 0.25), 0.5)
    assert len(seps.step) == 0 and len(seps.first) == len(seps.second) == 0
