"""The continuous stage in space: voxel regions, downwash-scaled corridors, the 3-D certificate and checks.

The discrete paths are built by hand on small voxel maps so that they keep the discrete
invariant with downwash 2 (every pair at least one cell apart in the scaled metric, at
steps and along the moves; every move half a cell from occupied voxels), as the 3-D
discrete stage does.
"""

from __future__ import annotations

import itertools
from functools import cache

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from scipy.optimize import minimize

from mrfswarm.config import SmoothingConfig
from mrfswarm.continuous import RecedingHorizon
from mrfswarm.continuous.certificate import certify, certify_pieces, control_point_stack, hull_distance_from_origin
from mrfswarm.continuous.formulation import LIMIT_PARTS, POLYGON, POLYGON_INNER, limit_polytope, piece_maps
from mrfswarm.continuous.receding_horizon import exact_min_separation
from mrfswarm.continuous.regions import (
    Regions,
    box_cube_distance,
    build_regions,
    region_clearance,
    separations,
)
from mrfswarm.continuous.sampled_check import check_positions, uniform_times, voxel_clearance
from mrfswarm.errors import ScenarioError
from mrfswarm.geometry import downwash_scale
from mrfswarm.maps import OccupancyGrid
from mrfswarm.trajectory import PiecewisePolynomial, max_derivative_norms
from mrfswarm.trajectory.bernstein import control_points

RADIUS = 0.25
DOWNWASH = 2.0


def window_wall() -> OccupancyGrid:
    """16 x 5 x 6 voxels, a wall at x = 6 with a window one voxel wide at y = 2, z = 2..4."""
    prob = np.zeros((16, 5, 6))
    prob[6] = 1.0
    prob[6, 2, 2:5] = 0.0
    return OccupancyGrid(prob)


def window_paths() -> np.ndarray:
    """Six robots in two layers two voxels apart (one cell in the scaled metric with downwash 2) and
    two voxels apart along x: they rise, fly through the window as one column, then the layers part
    (the lower one diagonally down, the upper one up) and the last robots slow down."""
    starts = np.array([[x, 2, z] for z in (1, 3) for x in (0, 2, 4)])  # (6, 3)
    steps = [starts, starts + [0, 0, 1]]
    for _ in range(9):
        steps.append(steps[-1] + [1, 0, 0])
    last = steps[-1].copy()
    low = last[:, 2] == 2
    last[low] += [1, 0, -1]
    last[~low] += [1, 0, 1]
    steps.append(last)
    return np.stack(steps)


@cache
def window_plan(backend: str = "piqp"):
    cfg = SmoothingConfig(backend=backend, check_rate_hz=500.0)
    rh = RecedingHorizon(window_paths(), window_wall(), cfg, RADIUS, workers=1, downwash=DOWNWASH)
    return rh, rh.run()


def brute_check(trajectories, grid: OccupancyGrid, scale: np.ndarray, rate_hz: float = 500.0) -> dict:
    """Every pair and every occupied voxel at every sample: scaled separation, clearance, off the map."""
    T = trajectories[0].duration
    t = np.linspace(0.0, T, int(np.ceil(T * rate_hz)) + 1)
    pts = np.stack([tr.evaluate(t) for tr in trajectories], axis=1)  # (S, N, d)
    sep = min(float(np.linalg.norm((pts[:, i + 1:] - pts[:, i:i + 1]) * scale, axis=-1).min())
              for i in range(pts.shape[1] - 1))
    occ = grid.cell_to_world(np.argwhere(grid.occupied))
    flat = pts.reshape(-1, pts.shape[-1])
    gap = np.maximum(0.0, np.abs(flat[:, None, :] - occ[None]) - grid.resolution / 2)
    clr = float(np.linalg.norm(gap, axis=-1).min(initial=np.inf))
    lo, hi = grid.bounds
    off = bool(((flat < lo) | (flat > hi)).any())
    return {"separation": sep, "clearance": clr, "off_map": off, "points": pts, "times": t}


def test_discrete_window_paths_keep_the_scaled_invariant():
    """The hand-made plan is what the 3-D discrete stage hands over (else the tests below prove nothing)."""
    P = window_paths().astype(float)
    s = downwash_scale(3, DOWNWASH)
    grid = window_wall()
    assert grid.is_free(window_paths()).all()
    for a, b in zip(P[:-1], P[1:]):
        for u in np.linspace(0, 1, 11):
            x = (a + u * (b - a)) * s
            d = np.linalg.norm(x[:, None] - x[None], axis=-1) + np.eye(len(x)) * 9
            assert d.min() >= 1.0 - 1e-12
    assert np.ptp(P[:, :, 2]) > 0  # z moves


def test_a_swarm_passes_a_window_certified_and_checked_at_500_hz():
    rh, c = window_plan()
    assert c.certificate.ok and c.dim == 3 and c.downwash == DOWNWASH
    assert all(w.attempt and w.attempt != "witness" for w in c.windows)  # every window solved and certified
    grid = window_wall()
    dense = brute_check(c.trajectories, grid, downwash_scale(3, DOWNWASH))
    assert dense["separation"] >= 2 * RADIUS and dense["clearance"] >= RADIUS and not dense["off_map"]
    assert c.min_separation == pytest.approx(dense["separation"], abs=2e-3)  # exact vs 500 Hz
    assert c.min_separation_scaled == c.min_separation
    assert c.certificate.separation_bound <= c.min_separation + 1e-12
    # the stage's own sampled check (500 Hz) agrees and finds nothing
    assert c.sampled is not None and c.sampled.in_obstacle is None
    assert c.sampled.min_separation == pytest.approx(dense["separation"], abs=1e-9)
    assert c.sampled.min_clearance == pytest.approx(dense["clearance"], abs=1e-9)
    assert c.sampled.min_clearance >= RADIUS
    # the z polynomials are real: z changes, and the trajectories end where the discrete plan does
    z = dense["points"][..., 2]
    assert np.ptp(z, axis=0).min() >= 0.99
    end = c.positions(np.array([c.makespan_s]))[0]
    np.testing.assert_allclose(end, grid.cell_to_world(window_paths()[-1]), atol=1e-9)
    sm = SmoothingConfig()
    assert c.v_max <= sm.v_max and c.a_max <= sm.a_max and c.j_max <= sm.j_max
    # control points in their regions, each step
    from mrfswarm.continuous.merge_pieces import step_pieces

    steps = step_pieces(c.trajectories, c.knot_times)
    cps = np.stack([control_points(tr) for tr in steps], axis=1)  # (T, N, D + 1, 3)
    assert c.regions.violation(cps).max() == 0.0


def test_downwash_makes_the_stacked_layers_bind():
    """The layers fly two voxels (2 m) apart in z: 1 m in the scaled metric, the discrete minimum; the
    corridors between them let z shrink to 2 x 2r = 1 m only, where the plain metric would allow 0.5 m."""
    rh, c = window_plan()
    assert 2 * RADIUS <= c.min_separation <= 1.0 + 1e-6
    plain = exact_min_separation(c.trajectories, 2.0)
    assert plain >= c.min_separation + 0.4  # the closest pairs are stacked: their z halved by the scaling
    assert len(rh.seps) and np.any(np.abs(rh.seps.normal[:, 2]) > 0)  # corridors across z ...
    n = rh.seps.normal / downwash_scale(3, DOWNWASH)
    np.testing.assert_allclose(np.linalg.norm(n, axis=-1), 1.0)  # ... unit normals of the scaled space


def test_uav_csv_of_a_3d_trajectory_holds_its_real_z(tmp_path):
    from mrfswarm.trajectory import read_uav_csv, write_uav_csv

    _, c = window_plan()
    tr = c.trajectories[3]
    write_uav_csv(tr, tmp_path / "r.csv", altitude=7.0)  # the altitude is for planar trajectories only
    back = read_uav_csv(tmp_path / "r.csv", dim=3)
    t = np.linspace(0, tr.duration, 50)
    np.testing.assert_allclose(back.evaluate(t), tr.evaluate(t), atol=1e-9)
    assert np.ptp(back.evaluate(t)[:, 2]) > 1.0


def test_three_d_regions_are_boxes_shrunk_by_the_radius_and_clear_of_voxels():
    grid = window_wall()
    reg = build_regions(window_paths(), grid, RADIUS)
    assert reg.axes.shape[2:] == (3, 3) and reg.corners().shape[2:] == (8, 3)
    clr = region_clearance(reg, grid, 2 * RADIUS)
    assert clr.min() >= RADIUS - 1e-12
    # against every voxel, off-map ones (a wall around the map) included
    occ = np.pad(grid.occupied, 2, constant_values=True)
    cells = np.argwhere(occ) - 2
    gap = np.maximum(0, np.maximum(reg.lower[..., None, :] - cells - 0.5, cells - 0.5 - reg.upper[..., None, :]))
    brute = np.minimum(np.linalg.norm(gap, axis=-1).min(axis=-1), 2 * RADIUS)
    np.testing.assert_allclose(clr, brute, atol=1e-12)
    assert (clr < 2 * RADIUS).any()  # the window's regions come near the wall
    # the steps through the window: a box a voxel wide, shrunk by the radius on each side
    P = grid.cell_to_world(window_paths())
    X = reg.lower <= P[:-1] + 1e-12
    assert X.all() and (reg.upper >= P[1:] - 1e-12).all()


def test_oriented_regions_in_space_keep_the_half_cell_tube():
    """A diagonal move whose bounding box is not free gets an oriented box: an orthonormal frame, every
    point within 1/2 - r of the segment, and exactly the radius from the voxels it passes."""
    prob = np.zeros((6, 6, 6))
    prob[1, 1, 3] = 1.0  # a voxel in the move (1,1,1) -> (3,3,3)'s bounding box, 0.816 from the segment
    grid = OccupancyGrid(prob)
    paths = np.array([[[1, 1, 1]], [[3, 3, 3]]])
    reg = build_regions(paths, grid, RADIUS)
    assert reg.oriented[0, 0]
    A = reg.axes[0, 0]
    np.testing.assert_allclose(A @ A.T, np.eye(3), atol=1e-12)
    corners = reg.corners()[0, 0]
    p, q = grid.cell_to_world(paths[:, 0])
    u = (q - p) / np.linalg.norm(q - p)
    s = np.clip((corners - p) @ u, 0, np.linalg.norm(q - p))
    far = np.linalg.norm(corners - (p + s[:, None] * u), axis=-1).max()
    assert far == pytest.approx(0.5 - RADIUS, rel=1e-6)
    clr = region_clearance(reg, grid, 2.0)[0, 0]
    # sampled: every point of the box vs the voxel's cube
    rng = np.random.default_rng(0)
    w = rng.uniform(size=(20000, 3))
    pts = (reg.lower[0, 0] + w * (reg.upper[0, 0] - reg.lower[0, 0])) @ A
    gap = np.linalg.norm(np.maximum(0, np.abs(pts - [1, 1, 3]) - 0.5), axis=-1)
    assert 0.816 - (0.5 - RADIUS) <= clr <= gap.min() + 1e-12


def random_boxes(rng, n):
    q, _ = np.linalg.qr(rng.normal(size=(n, 3, 3)))
    axes = np.swapaxes(q, -1, -2)
    lower = rng.uniform(-1.5, 0.5, (n, 3))
    upper = lower + rng.uniform(0.05, 1.5, (n, 3))
    center = rng.uniform(-2.5, 2.5, (n, 3))
    return axes, lower, upper, center


def sampled_box_cube(axes, lower, upper, center, half, rng, k=4000):
    """An upper bound on the distance by sampling both solids' surfaces (faces of each)."""
    out = []
    for A, lo, hi, c in zip(axes, lower, upper, center):
        u = rng.uniform(size=(k, 3))
        face = rng.integers(0, 3, k)
        u[np.arange(k), face] = rng.integers(0, 2, k)
        bp = (lo + u * (hi - lo)) @ A
        v = rng.uniform(size=(k, 3))
        v[np.arange(k), face] = rng.integers(0, 2, k)
        cp = c - half + 2 * half * v
        # every box point against the cube, every cube point against the box: exact one-sided distances
        g1 = np.linalg.norm(np.maximum(0, np.abs(bp - c) - half), axis=-1).min()
        s = cp @ A.T
        g2 = np.linalg.norm(np.maximum(0, np.maximum(lo - s, s - hi)), axis=-1).min()
        out.append(min(g1, g2))
    return np.array(out)


@pytest.mark.parametrize("seed", range(4))
def test_box_cube_distance_against_sampling(seed):
    rng = np.random.default_rng(seed)
    axes, lower, upper, center = random_boxes(rng, 60)
    d = box_cube_distance(axes, lower, upper, center, 0.5)
    ref = sampled_box_cube(axes, lower, upper, center, 0.5, rng)
    assert (d <= ref + 1e-9).all()  # never above a distance that is attained
    assert np.abs(d - ref).max() < 0.05  # and close to it (sampling's own error)
    # meeting: a point of the box inside the cube means distance 0, and the other way round
    mid = np.einsum("nk,nka->na", (lower + upper) / 2, axes)
    inside = np.linalg.norm(np.maximum(0, np.abs(mid - center) - 0.5), axis=-1) == 0
    assert (d[inside] == 0).all()


def test_box_cube_distance_of_axis_aligned_boxes_is_the_gap():
    rng = np.random.default_rng(5)
    lower = rng.uniform(-3, 0, (200, 3))
    upper = lower + rng.uniform(0.1, 2, (200, 3))
    center = rng.uniform(-3, 3, (200, 3))
    d = box_cube_distance(np.broadcast_to(np.eye(3), (200, 3, 3)), lower, upper, center, 0.5)
    gap = np.maximum(0, np.maximum(lower - center - 0.5, center - 0.5 - upper))
    np.testing.assert_allclose(d, np.linalg.norm(gap, axis=-1), atol=1e-12)


def brute_hull_distance_3d(points: np.ndarray) -> float:
    """Min-norm point of the hull by SLSQP over the simplex (a check independent of the candidates)."""
    K = len(points)
    res = minimize(lambda w: float(np.sum((w @ points) ** 2)), np.full(K, 1 / K),
                   jac=lambda w: 2 * points @ (w @ points), bounds=[(0, 1)] * K,
                   constraints=[{"type": "eq", "fun": lambda w: w.sum() - 1}], method="SLSQP",
                   options={"ftol": 1e-15, "maxiter": 500})
    return float(np.sqrt(max(res.fun, 0.0)))


@pytest.mark.parametrize("seed", range(6))
def test_hull_distance_in_space_is_a_lower_bound_exact_outside(seed):
    rng = np.random.default_rng(seed)
    pts = rng.normal(size=(40, 8, 3)) * rng.uniform(0.1, 1.5, (40, 1, 3)) + rng.normal(scale=1.5, size=(40, 1, 3))
    d = hull_distance_from_origin(pts)
    for p, v in zip(pts, d):
        ref = brute_hull_distance_3d(p)
        w = rng.dirichlet(np.ones(8), 4000)
        assert v <= np.linalg.norm(w @ p, axis=-1).min() + 1e-12  # below every point of the hull
        assert v == pytest.approx(ref, abs=1e-6)


def test_hull_distance_in_space_of_flat_and_degenerate_sets():
    square = np.array([[1.0, -1, -1], [1, 1, -1], [1, 1, 1], [1, -1, 1]])
    assert hull_distance_from_origin(square[None])[0] == pytest.approx(1.0)  # a facet faces the origin
    around = np.concatenate([square, square * [-1, 1, 1]])
    assert hull_distance_from_origin(around[None])[0] == 0.0  # a cube around the origin
    line = np.array([[1.0, 1, 0], [1, -1, 0], [1, 0, 0]])
    assert hull_distance_from_origin(line[None])[0] == pytest.approx(1.0)
    same = np.tile([[0.0, 0.0, 2.0]], (4, 1))
    assert hull_distance_from_origin(same[None])[0] == pytest.approx(2.0)


def piece(points: np.ndarray, T: float = 1.0) -> PiecewisePolynomial:
    """A trajectory through ``points`` (K, d) piecewise linear, as a degree-7 polynomial per segment."""
    p = np.asarray(points, dtype=float)
    a = np.zeros((len(p) - 1, 8, p.shape[1]))
    a[:, 0], a[:, 1] = p[:-1], (p[1:] - p[:-1]) / T
    return PiecewisePolynomial(np.full(len(p) - 1, T), a)


def open_regions(M: int, N: int, d: int = 3) -> Regions:
    return Regions(np.broadcast_to(np.eye(d), (M, N, d, d)).copy(), np.full((M, N, d), -50.0),
                   np.full((M, N, d), 50.0), np.zeros((M, N), bool), RADIUS)


def test_the_certificate_refuses_a_pair_too_close_in_the_scaled_metric():
    """Guard: robot B passes 0.8 m above robot A. Plainly that is apart (0.8 >= 0.5 m), but with
    downwash 2 it is 0.4 m in the scaled metric: the certificate refuses it, and the samples agree."""
    a = piece([[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [2.0, 0.0, 1.0]])
    b = piece([[2.0, 0.0, 1.8], [1.0, 0.0, 1.8], [0.0, 0.0, 1.8]])
    knots = np.array([0.0, 1.0, 2.0])
    limits = (10.0, 10.0, 10.0)
    plain = certify([a, b], knots, open_regions(2, 2), 2 * RADIUS, limits)
    assert plain.ok
    scaled = certify([a, b], knots, open_regions(2, 2), 2 * RADIUS, limits, downwash_scale(3, DOWNWASH))
    assert not scaled.ok and "not proven apart" in scaled.problems[0]
    assert scaled.separation_bound == pytest.approx(0.4)
    assert exact_min_separation([a, b], 2.0, scale=downwash_scale(3, DOWNWASH)) == pytest.approx(0.4)
    t = uniform_times(0.0, 2.0, 500.0)
    pts = np.stack([a.evaluate(t), b.evaluate(t)], axis=1)
    grid = OccupancyGrid(np.zeros((4, 3, 4)), origin=(-1.0, -1.0, 0.0))
    assert check_positions(t, pts, grid, downwash_scale(3, DOWNWASH)).min_separation == pytest.approx(0.4, abs=1e-9)
    assert check_positions(t, pts, grid).min_separation == pytest.approx(0.8, abs=1e-9)


def test_the_certificate_refuses_a_climb_through_a_voxel():
    """Guard: a robot whose z passes through an occupied voxel leaves the region the voxel bounds."""
    prob = np.zeros((3, 3, 5))
    prob[1, 1, 2] = 1.0
    grid = OccupancyGrid(prob)
    paths = np.array([[[1, 1, 0]], [[1, 1, 1]]])  # a safe step: up by one below the voxel
    reg = build_regions(paths, grid, RADIUS)
    climb = piece([[1.0, 1.0, 0.0], [1.0, 1.0, 2.0]])  # flies up into the voxel instead
    cert = certify([climb], np.array([0.0, 1.0]), reg, 2 * RADIUS, (10.0, 10.0, 10.0))
    assert not cert.ok and "leaves its region" in cert.problems[0]
    t = uniform_times(0.0, 1.0, 500.0)
    chk = check_positions(t, climb.evaluate(t)[:, None, :], grid)
    assert chk.in_obstacle is not None and chk.min_clearance == 0.0


def test_the_certificate_bounds_speed_over_three_axes():
    """Guard: a climb at 2 m/s in z and 2 m/s in x is 2.83 m/s: refused at v_max 2.5, passed at 3."""
    tr = piece([[0.0, 0.0, 0.0], [2.0, 0.0, 2.0]])
    cps = control_point_stack([tr])
    assert not certify_pieces(cps, open_regions(1, 1), 2 * RADIUS, (2.5, 100.0, 100.0)).ok
    ok = certify_pieces(cps, open_regions(1, 1), 2 * RADIUS, (3.0, 100.0, 100.0))
    assert ok.ok and ok.limit_bounds[0] == pytest.approx(np.sqrt(8))


def test_the_limit_polytope_lies_in_the_ball_and_holds_its_inner_ball():
    faces, inner = limit_polytope(3)
    assert faces.shape == (13, 3)
    np.testing.assert_allclose(np.linalg.norm(faces, axis=1), 1.0)
    rng = np.random.default_rng(1)
    v = rng.normal(size=(200000, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    # the polytope's support along v: the largest |x| it holds in that direction is inner / max_k |n_k . v|
    reach = inner / np.abs(v @ faces.T).max(axis=1)
    assert reach.max() <= 1.0 and reach.max() > 0.999  # inscribed: inside the unit ball, touching it
    assert reach.min() >= inner - 1e-12
    faces, inner = limit_polytope(2)
    assert faces is POLYGON and inner == POLYGON_INNER and faces.shape == (8, 2)
    np.testing.assert_allclose(np.linalg.norm(faces, axis=1), 1.0)
    theta = np.linspace(0.0, 2 * np.pi, 100001)
    reach = inner / np.abs(np.stack([np.cos(theta), np.sin(theta)], axis=1) @ faces.T).max(axis=1)
    assert reach.max() <= 1.0 + 1e-12 and reach.min() >= inner - 1e-12  # inscribed in the disc, holding its inner one
    # the grid's eight moves (axes, diagonals) point at vertices: a straight run may fly at the limit itself
    moves = np.array([[1, 0], [0, 1], [1, 1], [1, -1], [-1, 0], [0, -1], [-1, -1], [-1, 1]]) / np.array(
        [1, 1, np.sqrt(2), np.sqrt(2), 1, 1, np.sqrt(2), np.sqrt(2)])[:, None]
    np.testing.assert_allclose(inner / np.abs(moves @ faces.T).max(axis=1), 1.0, rtol=1e-12)
    with pytest.raises(ValueError, match="2 or 3"):
        limit_polytope(4)


def test_voxel_clearance_is_exact_against_every_voxel():
    rng = np.random.default_rng(2)
    occ = rng.uniform(size=(12, 10, 8)) < 0.05
    pts = rng.uniform(-0.5, 7.5, (3000, 3))  # on the map
    gap = np.maximum(0, np.abs(pts[:, None] - np.argwhere(occ)[None]) - 0.5)
    edge = np.minimum(pts + 0.5, np.array(occ.shape) - 0.5 - pts).min()
    inner = pts[np.minimum(pts + 0.5, np.array(occ.shape) - 0.5 - pts).min(axis=1) > 1.0]
    gap_inner = np.maximum(0, np.abs(inner[:, None] - np.argwhere(occ)[None]) - 0.5)
    assert voxel_clearance(occ, inner, k=2) == pytest.approx(np.linalg.norm(gap_inner, axis=-1).min(), abs=1e-12)
    assert voxel_clearance(occ, pts, k=2) == pytest.approx(min(np.linalg.norm(gap, axis=-1).min(), edge), abs=1e-12)
    # no obstacle: the floor, the ceiling and the walls of the map are still there
    assert voxel_clearance(np.zeros((3, 3, 3), bool), np.array([[1.0, 1.0, 1.9]])) == pytest.approx(0.6)


def test_separations_in_the_scaled_space_refuse_a_plan_that_breaks_the_invariant():
    """Guard: two robots stacked one voxel apart are 0.5 cell apart with downwash 2 (the voxel right above)."""
    grid = OccupancyGrid(np.zeros((3, 3, 4)))
    paths = np.array([[[1, 1, 1], [1, 1, 2]], [[1, 1, 1], [1, 1, 2]]])
    reg = build_regions(paths, grid, 0.3)
    X = grid.cell_to_world(paths)
    assert len(separations(X, reg, 0.6)) == 1  # plainly 1 m apart: fine
    with pytest.raises(ScenarioError, match="downwash-scaled"):
        separations(X, reg, 0.6, downwash_scale(3, DOWNWASH))


def test_paths_and_grid_of_different_dimensions_are_refused():
    with pytest.raises(ValueError, match="axes"):
        RecedingHorizon(window_paths()[:, :, :2], window_wall(), SmoothingConfig(), RADIUS)


@pytest.mark.parametrize("d", [2, 3])
def test_a_crossing_is_certified_in_the_plane_and_in_space(d, dense_check):
    """The same end-to-end check in 2-D and 3-D: two robots swap places around each other."""
    shape = (7, 5) if d == 2 else (7, 5, 4)
    grid = OccupancyGrid(np.zeros(shape))
    lift = [0] * (d - 2)
    a = [[x, 1, *lift] for x in range(1, 6)]
    b = [[x, 3, *[2] * (d - 2)] for x in range(5, 0, -1)]
    paths = np.stack([a, b], axis=1)
    rh = RecedingHorizon(paths, grid, SmoothingConfig(), RADIUS, workers=1, downwash=DOWNWASH)
    c = rh.run()
    assert c.certificate.ok and c.trajectories[0].dim == d
    dense = brute_check(c.trajectories, grid, downwash_scale(d, DOWNWASH))
    assert dense["separation"] >= 2 * RADIUS and not dense["off_map"]
    assert c.min_separation == pytest.approx(dense["separation"], abs=2e-3)
    if d == 2:  # the shared brute-force check of the planar tests agrees
        assert dense_check(c.trajectories, grid, 500.0)["separation"] == pytest.approx(dense["separation"])


def test_scaled_checks_change_nothing_in_the_plane():
    """downwash_scale is ones in 2-D: the scaled certificate and checks are the plain ones, bit for bit."""
    tr = [piece([[0.0, 0.0], [1.0, 0.7]]), piece([[1.0, 0.0], [0.0, 0.8]])]
    knots = np.array([0.0, 1.0])
    reg = open_regions(1, 2, d=2)
    a = certify(tr, knots, reg, 0.5, (9.0, 9.0, 9.0))
    b = certify(tr, knots, reg, 0.5, (9.0, 9.0, 9.0), downwash_scale(2, DOWNWASH))
    assert a == b
    assert exact_min_separation(tr, 2.0) == exact_min_separation(tr, 2.0, scale=downwash_scale(2, DOWNWASH))


def test_every_pair_of_faces_is_looked_at():
    """The 3-D hull bound sees each triangle: points on a facet far from every edge's nearest point."""
    tri = np.array([[3.0, -5, -5], [3, 10, -5], [3, -5, 10]])
    assert hull_distance_from_origin(tri[None])[0] == pytest.approx(3.0)
    for perm in itertools.permutations(range(3)):
        assert hull_distance_from_origin(tri[list(perm)][None])[0] == pytest.approx(3.0)


def test_the_pipeline_threads_the_downwash_and_the_plane_ignores_it():
    """scenario.downwash reaches the continuous stage; in the plane it changes nothing, bit for bit."""
    import mrfswarm
    from mrfswarm.pipeline import plan
    from support.repository import EXPERIMENTS

    base = ["simulation.enabled=false"]
    one = plan(mrfswarm.load_config(EXPERIMENTS / "free5.toml", base)).continuous
    two = plan(mrfswarm.load_config(EXPERIMENTS / "free5.toml", base + ["scenario.downwash=2"])).continuous
    assert one.downwash == 1.0 and two.downwash == 2.0
    for a, b in zip(one.trajectories, two.trajectories):
        assert np.array_equal(a.coefficients, b.coefficients) and np.array_equal(a.durations, b.durations)
    assert one.min_separation == two.min_separation


MOVES_3D = np.array([m for m in np.ndindex(3, 3, 3)]) - 1  # the 26-neighbourhood and staying


def scaled_apart(a: np.ndarray, b: np.ndarray, scale: np.ndarray) -> bool:
    """Every pair of robots moving straight from ``a`` to ``b`` (N, 3) stays one cell apart in the scaled metric."""
    for u in np.linspace(0, 1, 21):
        x = (a + u * (b - a)) * scale
        if (np.linalg.norm(x[:, None] - x[None], axis=-1) + 9 * np.eye(len(x))).min() < 1.0 - 1e-9:
            return False
    return True


@settings(max_examples=5, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 10_000))
def test_random_voxel_swarms_with_downwash(seed):
    """A packed block in space (one voxel apart across, two along z: one cell with downwash 2) flying
    random 26-neighbour moves among random voxels, and a robot on its own crossing its way: certified,
    and the brute-force check at 500 Hz finds scaled separation >= 2r, clearance >= r, nothing off the map."""
    rng = np.random.default_rng(seed)
    shape = np.array([12, 9, 8])
    scale = downwash_scale(3, 2.0)
    block = np.array([[i, j, 2 * k] for i in range(2) for j in range(2) for k in range(2)]) + [2, 2, 1]
    paths = [np.concatenate([[[9, 6, 5]], block])]
    for _ in range(6):
        now = paths[-1]
        for m in rng.permutation(MOVES_3D):  # the block: a move that keeps it on the map
            nxt = now + np.where(np.arange(len(now))[:, None] > 0, m, 0)
            if ((nxt >= 0) & (nxt < shape)).all():
                break
        for m in rng.permutation(MOVES_3D):  # the loner: a move that keeps it one cell from the block
            cand = nxt.copy()
            cand[0] = now[0] + m
            if ((cand >= 0) & (cand < shape)).all() and scaled_apart(now, cand, scale):
                break
        else:
            assume(False)
        paths.append(cand)
    P = np.array(paths)
    occ = rng.uniform(size=tuple(shape)) < 0.06
    t = np.linspace(0, 1, 41)[:, None, None, None]
    seg = (P[:-1][None] + t * (P[1:] - P[:-1])[None]).reshape(-1, 3)  # free every voxel near a move's tube
    cells = np.argwhere(occ)
    gap = np.linalg.norm(np.maximum(0, np.abs(seg[:, None] - cells[None]) - 0.5), axis=-1).min(axis=0)
    occ[tuple(cells[gap < 0.55].T)] = False
    grid = OccupancyGrid.from_occupied(occ)
    cfg = SmoothingConfig()
    c = RecedingHorizon(P, grid, cfg, 0.25, downwash=2.0, workers=1).run()
    assert c.certificate.ok, c.certificate.problems
    d = brute_check(c.trajectories, grid, scale)
    assert d["separation"] >= 0.5 - 1e-9 and d["clearance"] >= 0.25 - 1e-9 and not d["off_map"], d
    assert c.min_separation == pytest.approx(d["separation"], abs=2e-3)
    cps = np.stack([control_points(tr) for tr in c.trajectories], axis=1)
    assert c.regions.violation(cps).max() == 0.0
    for r, lim in zip((1, 2, 3), (cfg.v_max, cfg.a_max, cfg.j_max)):
        assert max_derivative_norms(c.trajectories, r).max() <= lim


def test_pieces_spanning_several_steps_in_space():
    """smoothing.max_pieces in 3-D: fewer polynomial pieces than steps, split at the steps for the certificate."""
    cfg = SmoothingConfig(horizon=8, execution=0.5, max_pieces=5)
    c = RecedingHorizon(window_paths(), window_wall(), cfg, RADIUS, workers=1, downwash=DOWNWASH).run()
    assert c.certificate.ok and c.pieces_fit
    assert max(c.pieces_per_robot) < len(c.knot_times) - 1
    dense = brute_check(c.trajectories, window_wall(), downwash_scale(3, DOWNWASH))
    assert dense["separation"] >= 2 * RADIUS and dense["clearance"] >= RADIUS and not dense["off_map"]


@pytest.mark.parametrize("growth", [0.5, 1.0, 1.5, 2.0])
def test_regions_grow_by_the_scaled_metric_and_only_over_free_voxels(growth):
    """With downwash c the boxes grow growth / c cells along z (growth along x and y), never over an
    occupied voxel (exact clearance against every voxel: >= the radius)."""
    rng = np.random.default_rng(int(growth * 10))
    occ = rng.uniform(size=(10, 9, 8)) < 0.12
    paths = np.array([[[4, 4, 4]], [[5, 4, 4]]])
    occ[4:6, 4, 4] = False
    grid = OccupancyGrid.from_occupied(occ)
    s = downwash_scale(3, DOWNWASH)
    reg = build_regions(paths, grid, RADIUS, growth, scale=s)
    plain = build_regions(paths, grid, RADIUS, growth)
    assert region_clearance(reg, grid, 3.0).min() >= RADIUS - 1e-12
    assert region_clearance(plain, grid, 3.0).min() >= RADIUS - 1e-12
    open_grid = OccupancyGrid(np.zeros((10, 9, 8)))
    free = build_regions(paths, open_grid, RADIUS, growth, scale=s)
    room = np.concatenate([[4, 4, 4] - free.lower[0, 0], free.upper[0, 0] - [5, 4, 4]]) + RADIUS - 0.5
    np.testing.assert_allclose(room, [growth, growth, growth / DOWNWASH] * 2, atol=1e-8)
    np.testing.assert_array_equal(build_regions(paths, open_grid, RADIUS, growth, scale=np.ones(3)).upper,
                                  build_regions(paths, open_grid, RADIUS, growth).upper)


def test_hull_distance_of_points_on_a_line_with_rounding_noise():
    """Robots stacked exactly above one another: relative control points on the z axis, with 1e-9 of noise
    across it. Slivers of triangles must not hide the distance (a plane through a near-line can pass
    the origin as near as the noise)."""
    rng = np.random.default_rng(3)
    z = np.sort(rng.uniform(0.55, 1.2, (200, 8)), axis=1)
    pts = np.stack([rng.normal(scale=1e-9, size=z.shape), rng.normal(scale=1e-9, size=z.shape), z], axis=-1)
    np.testing.assert_allclose(hull_distance_from_origin(pts), z[:, 0], atol=1e-8)


@pytest.mark.parametrize("d", [2, 3])
def test_limit_rows_per_face(d):
    """A mask per (step, robot, order) is the mask of all its faces, row for row; a mask per face keeps
    only those faces' rows (what the window loop switches on in space)."""
    from mrfswarm.continuous.formulation import WindowFormulation, WindowSpec

    rng = np.random.default_rng(d)
    M, G = 3, 2
    nf = len(limit_polytope(d)[0])
    reg = Regions(np.broadcast_to(np.eye(d), (M, G, d, d)).copy(), np.full((M, G, d), -9.0),
                  np.full((M, G, d), 9.0), np.zeros((M, G), bool), RADIUS)
    per_order = rng.uniform(size=(M, G, 3)) < 0.6

    def form(mask):
        return WindowFormulation(WindowSpec(
            degree=7, derivative=4, regions=reg, pair_step=np.zeros(0, int), pair_first=np.zeros(0, int),
            pair_second=np.zeros(0, int), pair_normal=np.zeros((0, d)), distance=0.5,
            start=np.zeros((G, 4, d)), end=np.ones((G, d)), origin=np.zeros((G, d)), limits=(2.0, 4.0, 4.0),
            time_scale=1.0, limit_mask=mask))

    T = np.array([1.0, 1.2, 0.9])
    a, b = form(per_order).qp(T), form(np.repeat(per_order[..., None], nf, axis=-1)).qp(T)
    assert (a.A != b.A).nnz == 0 and np.array_equal(a.l, b.l) and np.array_equal(a.u, b.u)
    one = np.zeros((M, G, 3, nf), bool)
    one[1, 0, 0, 2] = True  # one face of robot 0's velocity in step 1
    f, none = form(one), form(np.zeros((M, G, 3), bool))
    assert f.m - none.m == piece_maps(7, 4).rows[1]  # one row per velocity control point of the piece
    part = np.zeros((M, G, 3, nf, LIMIT_PARTS), bool)
    part[1, 0, 0, 2, 3] = True  # the same face, on the last part of the piece only
    assert form(part).m - none.m == piece_maps(7, 4).rows[1] // LIMIT_PARTS
    whole = f.qp(T).A.tocsr()
    every = form(np.repeat(one[..., None], LIMIT_PARTS, axis=-1)).qp(T).A.tocsr()
    assert (every != whole).nnz == 0  # a mask per face is the mask of all its parts
    first = M * G * 8 * d  # the limit rows follow the region rows (8 position control points per piece, d slabs)
    R = piece_maps(7, 4).rows[1] // LIMIT_PARTS
    mine = form(part).qp(T).A.tocsr()[first:first + R]
    # the face's rows on the last part: control points 3R..4R - 1 of the piece, every LIMIT_PARTS-th row of all
    assert mine.nnz > 0 and (mine != whole[first + LIMIT_PARTS - 1:first + LIMIT_PARTS * R:LIMIT_PARTS]).nnz == 0
