"""Waypoint pruning per horizon, on hand-checked cases."""

import numpy as np
import pytest

from mrfswarm.discrete.pruning import horizon_bounds, prune_paths
from mrfswarm.geometry import segment_clear


def test_horizon_bounds():
    assert horizon_bounds(10, 4) == [(0, 4), (4, 8), (8, 10)]
    assert horizon_bounds(4, 4) == [(0, 4)]
    assert horizon_bounds(0, 4) == [(0, 0)]
    with pytest.raises(ValueError):
        horizon_bounds(3, 0)


def test_straight_line_is_pruned_to_horizon_ends():
    free = np.ones((20, 5), bool)
    paths = np.array([[[x, 2]] for x in range(9)])  # one robot moving right for 8 steps
    kept = prune_paths(paths, free, horizon=4)
    assert kept[0].tolist() == [0, 4, 8]


def test_corner_around_an_obstacle_is_kept():
    free = np.ones((6, 6), bool)
    free[2:4, 2:4] = False  # a 2x2 block
    # around the block: (1,1) -> (1,4) -> (4,4), one cell per step
    path = [(1, 1), (1, 2), (1, 3), (1, 4), (2, 4), (3, 4), (4, 4)]
    paths = np.array([[p] for p in path])
    kept = prune_paths(paths, free, horizon=6)[0].tolist()
    assert kept[0] == 0 and kept[-1] == 6
    assert 3 in kept  # the corner (1, 4) cannot be cut: the shortcut crosses the block
    pts = paths[kept, 0]
    for a, b in zip(pts[:-1], pts[1:]):
        assert segment_clear(free, a, b)


def test_pruning_does_not_cross_another_robots_trajectory():
    free = np.ones((10, 10), bool)
    # robot 0 goes (0,0)->(1,1)->(2,0)->... a zig-zag whose shortcut (0,0)->(2,0) passes (1,0);
    # robot 1 moves through (1,0) during the window
    r0 = [(0, 0), (1, 1), (2, 0)]
    r1 = [(1, 3), (1, 2), (1, 0)]  # (a pruning input; it need not be a valid discrete motion)
    paths = np.array([[a, b] for a, b in zip(r0, r1)])
    assert prune_paths(paths, free, horizon=2)[0].tolist() == [0, 1, 2]
    # without robot 1 crossing, the zig-zag is cut
    paths2 = np.array([[a, (5, 5 + i)] for i, a in enumerate(r0)])
    assert prune_paths(paths2, free, horizon=2)[0].tolist() == [0, 2]


def test_segments_clear_is_segment_clear_for_every_segment():
    from mrfswarm.discrete.motion import segments_clear

    rng = np.random.default_rng(7)
    for density in (0.05, 0.3):
        free = rng.random((25, 25)) > density
        p = np.round(rng.uniform(-2, 26, (800, 2)))
        q = p + np.round(rng.uniform(-4, 4, (800, 2)))
        want = np.array([segment_clear(free, a, b) for a, b in zip(p, q)])
        assert 0.05 < want.mean() < 0.95
        np.testing.assert_array_equal(segments_clear(free, p, q), want)
    assert segments_clear(free, np.zeros((0, 2)), np.zeros((0, 2))).shape == (0,)
