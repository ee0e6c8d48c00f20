"""The discrete metrics (:mod:`mrfswarm.metrics`), on hand-checked cases."""

import numpy as np
import pytest

from mrfswarm.metrics import discrete_metrics, min_separation, obstacle_clearance


def test_min_separation_includes_moves():
    paths = np.array([[[0, 0], [3, 0]], [[1, 0], [2, 0]]])  # they approach to 1 cell
    assert min_separation(paths) == pytest.approx(1.0)
    paths = np.array([[[0, 0], [2, 0]], [[1, 1], [1, 0]]])  # the distance dips mid-move
    # relative start (-2, 0), relative motion (1,1)-(-1,0) = (2,1): closest approach 2/sqrt(5) < both ends
    assert min_separation(paths) == pytest.approx(2 / np.sqrt(5))


def test_obstacle_clearance_exact():
    occ = np.zeros((10, 10), bool)
    occ[5, 5] = True
    assert obstacle_clearance(occ, np.array([[2.0, 5.0]])) == pytest.approx(2.5)
    assert obstacle_clearance(occ, np.array([[3.5, 3.5]])) == pytest.approx(np.hypot(1, 1))
    assert obstacle_clearance(np.zeros((4, 4), bool), np.array([[1.0, 1.0]])) is None


def test_discrete_metrics_summary():
    occ = np.zeros((20, 20), bool)
    occ[10, :] = True
    paths = np.array([[[0, 0], [0, 3]], [[1, 0], [1, 3]], [[2, 0], [2, 3]]])
    m = discrete_metrics(paths, occ, resolution=0.5, goal=np.array([2, 1]), goal_radius=1.0)
    assert m.steps == 2
    np.testing.assert_allclose(m.path_lengths, [1.0, 1.0])  # 2 cells of 0.5 m
    np.testing.assert_allclose(m.mean_distance, [1.5, 1.5, 1.5])
    assert m.min_separation == pytest.approx(1.5)
    assert m.min_obstacle_clearance == pytest.approx((10 - 2 - 0.5) * 0.5)
    assert m.final_goal_distance == pytest.approx(np.hypot(0, 0.5) * 0.5)
    assert m.reached_goal is True
