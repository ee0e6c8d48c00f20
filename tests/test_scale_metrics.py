"""Distance statistics and clearance through spatial indices equal their all-pairs / all-points references."""

import numpy as np
import pytest
from scipy.spatial.distance import pdist

from mrfswarm.metrics import (
    ObstacleIndex,
    densify,
    distance_series,
    mean_pairs,
    min_pair_distances,
    obstacle_clearance,
    path_clearance,
)


def brute_min(points):
    S, N, _ = points.shape
    iu, ju = np.triu_indices(N, 1)
    d = np.hypot(*(points[:, iu] - points[:, ju]).transpose(2, 0, 1))
    k = np.argmin(d, axis=1)
    return d[np.arange(S), k], np.stack([iu[k], ju[k]], axis=1)


@pytest.mark.parametrize("seed", range(6))
def test_min_pair_distances_equal_all_pairs(seed):
    rng = np.random.default_rng(seed)
    N = int(rng.integers(2, 80))
    start = rng.normal(0, 4, (N, 2))
    vel = rng.normal(0, 0.3, (N, 2))
    t = np.linspace(0, 10, int(rng.integers(1, 200)))
    pts = start[None] + t[:, None, None] * vel[None]
    d, pairs = min_pair_distances(pts)
    bd, bp = brute_min(pts)
    np.testing.assert_allclose(d, bd, rtol=0, atol=1e-12)
    assert (pairs == bp).all()


def test_min_pair_distance_at_exactly_the_search_radius():
    """Pair (0, 1) starts exactly d_nn + 4 D apart and ties with the nearest pair at the chunk's end."""
    D = 0.5
    t0 = np.array([[10.0, 0.0], [11.0 + 4 * D, 0.0], [0.0, 0.0], [1.0, 0.0]])
    t1 = np.array([[10.0 + D, 0.0], [11.0 + 3 * D, 0.0], [-D, 0.0], [1.0 + D, 0.0]])
    d, pairs = min_pair_distances(np.stack([t0, t1]))
    assert d.tolist() == [1.0, 1.0 + 2 * D]
    assert pairs.tolist() == [[2, 3], [0, 1]]


def test_distance_series_mean_exact_for_small_swarms_sampled_for_large():
    rng = np.random.default_rng(0)
    small = rng.normal(0, 5, (30, 50, 2))
    ds = distance_series(small)
    assert ds.exact and ds.n_pairs == 50 * 49 // 2
    np.testing.assert_allclose(ds.mean, [pdist(p).mean() for p in small], rtol=1e-12)
    np.testing.assert_allclose(ds.min, [pdist(p).min() for p in small], rtol=1e-12)
    big = rng.normal(0, 5, (4, 400, 2))
    ds = distance_series(big, max_pairs=5000)
    assert not ds.exact and ds.n_pairs == 5000
    exact = np.array([pdist(p).mean() for p in big])
    assert np.all(np.abs(ds.mean / exact - 1) < 0.02)
    np.testing.assert_allclose(ds.min, [pdist(p).min() for p in big], rtol=1e-12)


def test_mean_pairs_are_distinct_ordered_and_seeded():
    pairs, exact = mean_pairs(300, 1000)
    assert not exact and len(pairs) == 1000
    assert np.all(pairs[:, 0] < pairs[:, 1]) and np.all(pairs[:, 1] < 300)
    assert len(np.unique(pairs[:, 0] * 300 + pairs[:, 1])) == 1000
    assert (mean_pairs(300, 1000)[0] == pairs).all()
    assert mean_pairs(45, 1000)[1] is True and len(mean_pairs(45, 1000)[0]) == 990


@pytest.mark.parametrize("seed", range(5))
def test_path_clearance_equals_every_densified_point(seed):
    rng = np.random.default_rng(seed)
    occ = rng.random((30, 30)) < 0.08
    N, T = int(rng.integers(1, 30)), int(rng.integers(0, 12))
    pos = rng.integers(0, 30, (N, 2))
    paths = [pos]
    for _ in range(T):
        pos = np.clip(pos + rng.integers(-1, 2, (N, 2)), -1, 30)  # off the map too
        paths.append(pos)
    paths = np.stack(paths)
    assert path_clearance(paths, occ) == obstacle_clearance(occ, densify(paths))
    # without obstacles the map's edge is what is near (a wall: off the map counts as one)
    assert path_clearance(paths, np.zeros_like(occ)) == obstacle_clearance(np.zeros_like(occ), densify(paths))
    assert ObstacleIndex(occ).clearance(paths) == obstacle_clearance(occ, paths)


def test_path_clearance_finds_a_corner_passed_mid_move():
    """Robot 1's long move starts and ends far from the obstacle but touches its corner mid-way;
    robot 0 stays 1.5 cells away, so the positions alone would say 1.5."""
    occ = np.zeros((10, 10), bool)
    occ[5, 5] = True
    paths = np.array([[[5, 7], [1, 8]], [[5, 7], [8, 1]]])
    assert ObstacleIndex(occ).clearance(paths) == 1.5
    assert path_clearance(paths, occ) == obstacle_clearance(occ, densify(paths)) == 0.0


def test_distance_series_mean_on_a_coarser_grid_when_long():
    """Past the work limit the mean is exact at evenly spaced samples and interpolated between them."""
    rng = np.random.default_rng(2)
    t = np.linspace(0, 1, 101)
    pts = rng.normal(0, 3, (1, 20, 2)) + t[:, None, None] * rng.normal(0, 3, (1, 20, 2))
    full = distance_series(pts)
    coarse = distance_series(pts, max_work=190 * 11)  # 190 pairs: every 10th sample
    assert coarse.exact and len(coarse.mean) == 101
    np.testing.assert_allclose(coarse.mean[::10], full.mean[::10], rtol=1e-12)
    np.testing.assert_allclose(coarse.mean, full.mean, rtol=1e-2)  # smooth motion: close in between
    assert not np.allclose(coarse.mean, full.mean, rtol=1e-12, atol=0)
    np.testing.assert_array_equal(coarse.min, full.min)
