"""The flight-quality measures: the makespan's lower bound and the stop count."""

from __future__ import annotations

import numpy as np

from mrfswarm.discrete.goal_distance import goal_distance
from mrfswarm.flight_quality import count_stops, free_path_lengths, makespan_lower_bound
from mrfswarm.trajectory import PiecewisePolynomial


def test_free_path_lengths_go_around_a_wall_without_cutting_corners():
    free = np.ones((7, 7), dtype=bool)
    free[3, 0:6] = False  # a wall with its gap at the top (y = 6)
    starts, ends = np.array([[0, 0], [0, 0]]), np.array([[6, 0], [1, 1]])
    lengths = free_path_lengths(free, starts, ends)
    assert lengths[1] == np.sqrt(2)  # one diagonal move
    assert lengths[0] > 12.0  # the straight 6 m are blocked
    via = free_path_lengths(free, ends, np.array([[6, 0], [6, 0]]))
    assert makespan_lower_bound(free, starts, ends, 1.0, 2.0) == lengths.max() / 2.0
    # pruning by the bound through a common cell keeps the maximum
    d_goal = goal_distance(free, np.array([6, 0])).path
    assert makespan_lower_bound(free, starts, ends, 1.0, 2.0, via=d_goal) == lengths.max() / 2.0
    assert np.isfinite(via).all()


def _line(durations, speeds):
    """A 1-D flight along x: one cubic piece per duration, knot speeds given, in the (..., 2) layout."""
    pieces, x = [], 0.0
    for T, (v0, v1) in zip(durations, zip(speeds[:-1], speeds[1:])):
        # cubic Hermite with position x -> x + (v0 + v1) T / 2 (the trapezoid's distance)
        dx = (v0 + v1) * T / 2
        c = np.zeros((4, 2))
        c[0, 0], c[1, 0] = x, v0
        c[2, 0] = (3 * dx - (2 * v0 + v1) * T) / T**2
        c[3, 0] = (-2 * dx + (v0 + v1) * T) / T**3
        pieces.append(c)
        x += dx
    return PiecewisePolynomial(np.array(durations, float), np.stack(pieces))


def test_a_stop_inside_the_flight_counts_and_the_ends_do_not():
    go_stop_go = _line([1.0, 1.0, 1.0, 1.0], [0.0, 1.0, 0.0, 1.0, 0.0])
    cruise = _line([1.0, 1.0, 1.0], [0.0, 1.0, 1.0, 0.0])
    stops = count_stops([go_stop_go, cruise])
    assert stops.per_robot.tolist() == [1, 0]
    assert stops.mean == 0.5 and (stops.mean_speed > 0).all()
