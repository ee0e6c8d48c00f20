"""The certificate: each of its checks fires on the violation it exists for, and agrees with brute force."""

import re

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial import ConvexHull

from mrfswarm.continuous.certificate import certify, certify_pieces, control_point_stack, hull_distance_from_origin
from mrfswarm.continuous.formulation import hermite_trajectory
from mrfswarm.continuous.receding_horizon import exact_min_separation
from mrfswarm.continuous.regions import Regions
from mrfswarm.geometry import point_segment_distance
from mrfswarm.trajectory import PiecewisePolynomial
from mrfswarm.trajectory.bernstein import control_points, monomial_to_bernstein


def brute_hull_distance(points: np.ndarray) -> float:
    """Distance from the origin to conv(points) via scipy's hull (0 inside)."""
    from scipy.spatial import QhullError

    try:
        hull = ConvexHull(points)
    except QhullError:  # degenerate (collinear): the hull is a segment
        i, j = np.argmin(points @ points[0]), np.argmax(points @ points[0])
        order = np.argsort(points @ (points[j] - points[i]))
        p, q = points[order[0]], points[order[-1]]
        return float(point_segment_distance(np.zeros(2), p, q))
    if np.all(hull.equations[:, :2] @ np.zeros(2) + hull.equations[:, 2] <= 1e-12):
        return 0.0
    v = points[hull.vertices]
    return float(point_segment_distance(np.zeros(2), v, np.roll(v, -1, axis=0)).min())


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 100_000), st.floats(-2, 2), st.floats(-2, 2))
def test_hull_distance_matches_scipy(seed, ox, oy):
    rng = np.random.default_rng(seed)
    pts = rng.normal(size=(8, 2)) * rng.uniform(0.1, 2.0) + [ox, oy]
    assert hull_distance_from_origin(pts[None])[0] == pytest.approx(brute_hull_distance(pts), abs=1e-12)


def test_bernstein_hull_contains_the_curve():
    rng = np.random.default_rng(0)
    c = rng.normal(size=(3, 8, 2))
    tr = PiecewisePolynomial(np.array([0.7, 1.3, 2.0]), c)
    for r in range(4):
        cps = control_points(tr, r)
        t = np.linspace(0, tr.duration, 2001)
        vals = tr.evaluate(t, r)
        piece = tr.piece_index(t)
        for i in range(3):  # every sample is inside its piece's control-point bounding box
            v = vals[piece == i]
            assert (v >= cps[i].min(axis=0) - 1e-9).all() and (v <= cps[i].max(axis=0) + 1e-9).all()
    # the ends of a piece are its first and last control points
    np.testing.assert_allclose(control_points(tr)[:, 0], tr.evaluate(tr.knots[:-1]), atol=1e-12)
    assert monomial_to_bernstein(3)[3].tolist() == [1, 1, 1, 1]


def _rest_piece_flight(ends: np.ndarray, durations: np.ndarray) -> list[PiecewisePolynomial]:
    """Robots flying straight rest-to-rest steps between the positions ``ends`` (T + 1, N, 2)."""
    T1, N = ends.shape[:2]
    out = []
    for i in range(N):
        Y = np.zeros((T1, 4, 2))
        Y[:, 0] = ends[:, i]
        out.append(hermite_trajectory(Y, np.zeros((T1 - 1, 0, 2)), durations, 7, 4))
    return out


def _boxes(lo: np.ndarray, hi: np.ndarray) -> Regions:
    T, N = lo.shape[:2]
    return Regions(np.broadcast_to(np.eye(2), (T, N, 2, 2)).copy(), lo, hi, np.zeros((T, N), bool), 0.25)


def _setting():
    """Two robots flying 1 m along x in 8 s, 1.19 m apart, their control-point boxes 0.46 m apart."""
    ends = np.array([[[0.0, 0.0], [1.1, 0.45]], [[1.0, 0.0], [2.1, 0.45]]])
    flight = _rest_piece_flight(ends, np.array([8.0]))
    regions = _boxes(np.array([[[-0.5, -0.2], [0.6, 0.25]]]), np.array([[[1.5, 0.2], [2.6, 0.65]]]))
    return flight, regions


def test_a_safe_flight_is_certified():
    flight, regions = _setting()
    cert = certify(flight, np.array([0.0, 8.0]), regions, 0.5, (2.0, 4.0, 4.0))
    assert cert.ok, cert.problems
    assert cert.separation_bound == 0.5 and cert.near_pairs == 1
    cert = certify(flight, np.array([0.0, 8.0]), regions, 1.0, (2.0, 4.0, 4.0))
    assert cert.separation_bound == 1.0  # all that is proven: at least the safety distance
    cert = certify(flight, np.array([0.0, 8.0]), regions, 1.18, (2.0, 4.0, 4.0))
    assert cert.ok and cert.separation_bound == 1.18
    t = np.linspace(0, 8, 999)
    for r in (1, 2, 3):
        assert cert.limit_bounds[r - 1] >= max(np.linalg.norm(tr.evaluate(t, r), axis=1).max() for tr in flight)


def test_leaving_a_region_is_caught():
    flight, regions = _setting()
    tight = Regions(regions.axes, regions.lower, regions.upper - [[[0.6, 0.0], [0.0, 0.0]]], regions.oriented, 0.25)
    cert = certify(flight, np.array([0.0, 8.0]), tight, 0.5, (2.0, 4.0, 4.0))
    assert not cert.ok and "robot 0 leaves its region in step 0" in cert.problems[0]
    assert "worst of" not in cert.problems[0]  # robot 1 stays in its region
    both = Regions(regions.axes, regions.lower, regions.upper - 0.6, regions.oriented, 0.25)
    cert = certify(flight, np.array([0.0, 8.0]), both, 0.5, (2.0, 4.0, 4.0))
    assert cert.problems[0].endswith(", the worst of 2 robots over")  # one problem names both robots' count


def test_robots_too_close_are_caught():
    flight, regions = _setting()
    cert = certify(flight, np.array([0.0, 8.0]), regions, 1.19, (2.0, 4.0, 4.0))
    assert not cert.ok and "robots 0 and 1 are not proven apart in step 0" in cert.problems[0]


@pytest.mark.parametrize("which, limits", [("speed", (0.2, 4.0, 4.0)), ("acceleration", (2.0, 0.1, 4.0)),
                                           ("jerk", (2.0, 4.0, 0.08))])
def test_limits_are_caught(which, limits):
    flight, regions = _setting()
    cert = certify(flight, np.array([0.0, 8.0]), regions, 0.5, limits)
    assert not cert.ok and re.search(f"robot [01]'s {which} control points reach", cert.problems[0])
    assert cert.problems[0].endswith(", the worst of 2 robots over")  # both fly the same move


def test_pieces_off_the_time_grid_are_caught():
    flight, regions = _setting()
    cert = certify(flight, np.array([0.0, 8.5]), regions, 0.5, (2.0, 4.0, 4.0))
    assert not cert.ok and "common time grid" in cert.problems[0]


def test_crossing_robots_fail_and_the_check_is_not_the_planners():
    """Two robots swapping places through each other: no half-plane was ever given to the certificate."""
    ends = np.array([[[0.0, 0.0], [2.0, 0.0]], [[2.0, 0.0], [0.0, 0.0]]])
    flight = _rest_piece_flight(ends, np.array([2.0]))
    regions = _boxes(np.array([[[-0.5, -0.5]] * 2]), np.array([[[2.5, 0.5]] * 2]))
    cert = certify_pieces(control_point_stack(flight), regions, 0.5, (5.0, 5.0, 5.0))
    assert not cert.ok and cert.separation_bound == 0.0


def test_exact_min_separation_against_dense_sampling():
    rng = np.random.default_rng(5)
    for _ in range(5):
        ends = rng.uniform(0, 6, (4, 6, 2))
        flight = _rest_piece_flight(ends, rng.uniform(0.5, 2.0, 3))
        t = np.linspace(0, flight[0].duration, 40001)
        pts = np.stack([tr.evaluate(t) for tr in flight], axis=1)
        iu, ju = np.triu_indices(6, 1)
        dense = np.linalg.norm(pts[:, iu] - pts[:, ju], axis=-1).min()
        for block in (1, 2, 8):  # steps taken one, two or all at a time: the same minimum
            exact = exact_min_separation(flight, 0.5, block=block)
            assert exact <= dense + 1e-9 and dense - exact < 1e-4
