"""The distance functions of mrfswarm.geometry in 3-D, against dense sampling and exact cases."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mrfswarm.geometry import (
    norm,
    point_box_distance,
    point_segment_distance,
    segment_box_distance,
    segment_clear,
    segment_segment_distance,
)

SAMPLES = 2001


def sampled_segment_segment(p1, q1, p2, q2, n=SAMPLES):
    """Segment 1 sampled densely, each sample's distance to segment 2 exact: an upper bound within |u| / n."""
    a = p1 + np.linspace(0, 1, n)[:, None] * (q1 - p1)  # (n, 3)
    return point_segment_distance(a, p2, q2).min()


coord = st.floats(-3, 3, allow_nan=False).map(lambda v: round(v, 2))
point3 = st.tuples(coord, coord, coord).map(np.array)


@settings(max_examples=300, deadline=None)
@given(p1=point3, q1=point3, p2=point3, q2=point3)
def test_segment_segment_distance_matches_dense_sampling_in_3d(p1, q1, p2, q2):
    d = float(segment_segment_distance(p1, q1, p2, q2))
    semi = sampled_segment_segment(p1, q1, p2, q2)
    # the exact distance never exceeds a sampled one, and the sampled one (segment 1 sampled,
    # segment 2 exact) is within the sampling step of it
    step = np.linalg.norm(q1 - p1) / (SAMPLES - 1)
    assert d <= semi + 1e-9
    assert semi <= d + step + 1e-9
    assert d == pytest.approx(float(segment_segment_distance(p2, q2, p1, q1)), abs=1e-9)  # symmetric


def test_segment_segment_distance_exact_cases_in_3d():
    z = np.zeros(3)
    # skew lines, closest points inside both segments (the case 2-D never has)
    assert segment_segment_distance(np.array([-1.0, 0, 0]), np.array([1.0, 0, 0]),
                                    np.array([0.0, -1, 2]), np.array([0.0, 1, 2])) == pytest.approx(2.0)
    # crossing
    assert segment_segment_distance(np.array([-1.0, 0, 0]), np.array([1.0, 0, 0]),
                                    np.array([0.0, -1, 0]), np.array([0.0, 1, 0])) == pytest.approx(0.0, abs=1e-12)
    # parallel, overlapping
    assert segment_segment_distance(z, np.array([2.0, 0, 0]), np.array([1.0, 0, 1]),
                                    np.array([3.0, 0, 1])) == pytest.approx(1.0)
    # degenerate (points)
    assert segment_segment_distance(z, z, np.array([3.0, 4, 0]), np.array([3.0, 4, 0])) == pytest.approx(5.0)
    # broadcast over many pairs
    many = segment_segment_distance(np.zeros((5, 3)), np.ones((5, 3)), np.full((5, 3), 2.0), np.full((5, 3), 3.0))
    assert many.shape == (5,) and np.allclose(many, np.sqrt(3))


def test_segment_segment_distance_in_2d_is_zero_where_segments_cross():
    d = segment_segment_distance(np.array([0.0, 0]), np.array([2.0, 2]), np.array([0.0, 2]), np.array([2.0, 0]))
    assert d < 1e-12
    assert segment_segment_distance(np.array([0.0, 0]), np.array([1.0, 0]), np.array([0.0, 1]),
                                    np.array([1.0, 1])) == pytest.approx(1.0)


def test_norm_is_hypot_in_the_plane_bit_for_bit():
    rng = np.random.default_rng(0)
    v = rng.normal(size=(1000, 2)) * 10
    assert np.array_equal(norm(v), np.hypot(v[:, 0], v[:, 1]))
    w = rng.normal(size=(100, 3))
    assert np.allclose(norm(w), np.linalg.norm(w, axis=1))


@settings(max_examples=200, deadline=None)
@given(p=point3, q=point3, c=st.tuples(*[st.integers(-2, 2)] * 3).map(lambda t: np.array(t, float)))
def test_segment_box_distance_matches_dense_sampling_in_3d(p, q, c):
    d = float(segment_box_distance(p, q, c))
    s = np.linspace(0, 1, SAMPLES)[:, None]
    pts = p + s * (q - p)
    sampled = float(point_box_distance(pts, c).min())  # point-cube distance is exact per sample
    step = np.linalg.norm(q - p) / (SAMPLES - 1)
    assert d <= sampled + 1e-9
    assert sampled <= d + step + 1e-9


def test_segment_box_distance_edge_case_needs_the_cube_edges():
    # a segment skew to a cube edge, closest to the edge's middle: no end of the segment and no
    # corner of the cube is the nearest point
    d = segment_box_distance(np.array([1.0, -2, 1]), np.array([1.0, 2, 1]), np.zeros(3))
    assert d == pytest.approx(np.hypot(0.5, 0.5))
    d = segment_box_distance(np.array([-2.0, 1.5, 0.6]), np.array([2.0, 1.5, 0.4]), np.zeros(3))
    assert d == pytest.approx(1.0)


def test_point_distances_in_3d():
    assert point_box_distance(np.array([2.0, 2.0, 2.0]), np.zeros(3)) == pytest.approx(np.sqrt(3) * 1.5)
    assert point_segment_distance(np.array([0.0, 1, 1]), np.zeros(3), np.array([2.0, 0, 0])) == pytest.approx(np.sqrt(2))


def test_segment_clear_in_3d_no_edge_or_corner_cutting():
    free = np.ones((3, 3, 3), bool)
    o = np.zeros(3)
    # a face diagonal in the z = 0 plane needs the two voxels beside its edge, not the one above
    for blocked, clear in (((1, 0, 0), False), ((0, 1, 0), False), ((0, 0, 1), True), ((1, 1, 1), True)):
        f = free.copy()
        f[blocked] = False
        assert segment_clear(f, o, np.array([1.0, 1, 0])) is clear, blocked
    # a space diagonal needs the whole 2 x 2 x 2 block
    for blocked in [(1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 0), (1, 0, 1), (0, 1, 1)]:
        f = free.copy()
        f[blocked] = False
        assert not segment_clear(f, o, np.array([1.0, 1, 1])), blocked
    f = free.copy()
    f[2, 2, 2] = False
    assert segment_clear(f, o, np.array([1.0, 1, 1]))
    # off the map counts as occupied
    assert not segment_clear(free, o, np.array([-1.0, 0, 0]))
