"""The whole-flight checks on the piece stack equal the one-trajectory-at-a-time references.

The references (``support.final_checks_reference``) are the code these replaced. The
certificate and the control points must be equal bit for bit (a last bit decides whether
a pair exactly at the safety distance is near), the exact minimum separation and the
exact maxima to 1e-12 relative; on random flights, on a planned crossing and on the edge
cases: one robot, a plan without steps (hover), robots exactly at the reach or at the
safety distance, ties, violated limits, 3-D and unequal pieces.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import mrfswarm
from mrfswarm.continuous.certificate import certify, control_point_stack
from mrfswarm.continuous.formulation import hermite_trajectory
from mrfswarm.continuous.merge_pieces import step_pieces
from mrfswarm.continuous.receding_horizon import exact_min_separation
from mrfswarm.continuous.regions import Regions
from mrfswarm.discrete.pruning import prune_paths, prune_paths_brute_force
from mrfswarm.pipeline import plan
from mrfswarm.trajectory import PiecewisePolynomial
from mrfswarm.trajectory.bernstein import control_point_matrix, tau_control_points
from mrfswarm.trajectory.piece_stack import map_coefficients, map_coefficients_in_order, stacked_tau_coefficients
from mrfswarm.trajectory.retiming import max_derivative_norm_all
from support import final_checks_reference as ref

LIMITS = (2.0, 2.0, 4.0)


def random_flight(rng: np.random.Generator, N: int, M: int, spread: float, dim: int = 2) -> list[PiecewisePolynomial]:
    """N robots on one time grid of M steps, random knot derivatives (not at rest), starting within ``spread``."""
    T = rng.uniform(0.5, 2.5, M)
    Y = np.zeros((M + 1, N, 4, dim))
    Y[:, :, 0] = rng.uniform(0, spread, (N, dim)) + np.cumsum(rng.normal(0, 0.6, (M + 1, N, dim)), axis=0)
    Y[:, :, 1:] = rng.normal(0, 0.5, (M + 1, N, 3, dim))
    return [hermite_trajectory(Y[:, i], np.zeros((M, 0, dim)), T, 7, 4) for i in range(N)]


def hover(points: np.ndarray, duration: float = 1.0) -> list[PiecewisePolynomial]:
    """Robots standing still at ``points`` (N, 2) for one piece (a plan without steps)."""
    return [PiecewisePolynomial(np.array([duration]), np.concatenate([p[None, None], np.zeros((1, 7, 2))], axis=1))
            for p in np.asarray(points, dtype=float)]


def boxes_around(rng: np.random.Generator, flight: list[PiecewisePolynomial], slack: tuple[float, float]) -> Regions:
    """A box per robot and step around its control points, grown by a random amount in ``slack`` (< 0: left)."""
    P = ref.control_point_stack(flight)[0].transpose(1, 0, 2, 3)  # (M, N, K, 2)
    lo, hi = P.min(axis=2), P.max(axis=2)
    lo, hi = lo - rng.uniform(*slack, lo.shape), hi + rng.uniform(*slack, hi.shape)
    M, N = lo.shape[:2]
    return Regions(np.broadcast_to(np.eye(2), (M, N, 2, 2)).copy(), lo, hi, np.zeros((M, N), bool), 0.25)


def assert_same_checks(flight: list[PiecewisePolynomial], regions: Regions, distance: float,
                       limits: tuple[float, float, float] = LIMITS, reach: float = 2.0) -> None:
    knots = flight[0].knots
    assert certify(flight, knots, regions, distance, limits) == ref.certify(flight, knots, regions, distance, limits)
    for new, old in zip(control_point_stack(flight), ref.control_point_stack(flight)):
        assert new.shape == old.shape and np.array_equal(new, old)
    for r in (1, 2, 3):
        assert max_derivative_norm_all(flight, r) == pytest.approx(ref.max_derivative_norm_all(flight, r), rel=1e-12)
    for block in (1, 8):
        new, old = exact_min_separation(flight, reach, block), ref.exact_min_separation(flight, reach, block)
        assert new == pytest.approx(old, rel=1e-12, abs=0.0)


@pytest.mark.parametrize("seed", range(12))
def test_random_flights(seed):
    rng = np.random.default_rng(seed)
    N, M = int(rng.integers(1, 40)), int(rng.integers(1, 12))
    flight = random_flight(rng, N, M, spread=float(rng.uniform(0.5, 12.0)))
    regions = boxes_around(rng, flight, (-0.02, 0.3))  # some robots leave their boxes
    limits = (float(rng.uniform(0.5, 3.0)), float(rng.uniform(0.5, 3.0)), float(rng.uniform(1.0, 6.0)))
    assert_same_checks(flight, regions, float(rng.uniform(0.1, 1.0)), limits, reach=float(rng.uniform(0.2, 3.0)))


@pytest.fixture(scope="module")
def crossing():
    """A 40-robot crossing of a free map, planned (the continuous stage included)."""
    n = 40
    overrides = ['scenario.map={kind="free", size=[60, 30]}',
                 f"scenario.start={{center=[10.0, 15.0], n_robots={n}, sigma={12.0 * math.sqrt(n / 1000):.6g}, seed=0}}",
                 "scenario.goal=[50, 15]", "interaction.k=7", "simulation.enabled=false"]
    return plan(mrfswarm.load_config(None, overrides), progress=False)


def test_a_planned_crossing(crossing):
    c = crossing.continuous
    # its pieces span several steps (a Crazyflie's 31 pieces); the checks are the steps'
    assert c.pieces_per_robot[0] < len(c.knot_times) - 1
    steps = step_pieces(c.trajectories, c.knot_times)
    distance = 2 * crossing.config.scenario.robot_radius
    assert certify(c.trajectories, c.knot_times, c.regions, distance, LIMITS) == \
        certify(steps, c.knot_times, c.regions, distance, LIMITS)
    assert_same_checks(steps, c.regions, distance)
    assert exact_min_separation(steps, 2.0) == c.min_separation
    tight = (c.v_max * 0.9, c.a_max * 0.9, c.j_max * 0.9)  # every limit fails, the same robot and step named
    assert_same_checks(steps, c.regions, 0.8, tight)


def test_pruning_a_planned_crossing(crossing):
    paths, free = crossing.discrete.paths, crossing.scenario.grid.free
    for horizon in (4, 8):
        assert ([g.tolist() for g in prune_paths(paths, free, horizon)]
                == [r.tolist() for r in prune_paths_brute_force(paths, free, horizon)])


def test_one_robot_and_a_plan_without_steps():
    rng = np.random.default_rng(0)
    one = random_flight(rng, 1, 5, 1.0)
    assert_same_checks(one, boxes_around(rng, one, (0.0, 0.1)), 0.5)
    assert exact_min_separation(one, 2.0) == float("inf")
    still = hover(rng.uniform(0, 3, (6, 2)))
    assert_same_checks(still, boxes_around(rng, still, (0.0, 0.1)), 0.5)
    assert max_derivative_norm_all(still, 1) == 0.0


def test_robots_exactly_at_the_reach_or_the_safety_distance():
    """Hovering 2 m apart: not within a reach of 2 (near means closer), found after the reach grows; 0.5 m apart:
    exactly at the safety distance, so not near for the certificate; touching: 0."""
    rng = np.random.default_rng(1)
    for pts, reach, expected in (([[0.0, 0.0], [2.0, 0.0]], 2.0, 2.0), ([[0.0, 0.0], [0.5, 0.0], [5.0, 5.0]], 2.0, 0.5),
                                 ([[1.0, 1.0], [1.0, 1.0]], 2.0, 0.0), ([[0.0, 0.0], [0.0, 9.0]], 0.5, 9.0)):
        still = hover(np.array(pts))
        assert exact_min_separation(still, reach) == expected
        assert_same_checks(still, boxes_around(rng, still, (0.0, 0.1)), 0.5, reach=reach)
    # two robots crossing each other's path at the same time, and two passing exactly 0.5 m apart
    ends = np.array([[[0.0, 0.0], [2.0, 0.0]], [[2.0, 0.0], [0.0, 0.0]]])
    for gap, expected in ((0.0, 0.0), (0.5, 0.5)):
        Y = np.zeros((2, 2, 4, 2))
        Y[:, :, 0] = ends + [[0.0, 0.0], [0.0, gap]]
        flight = [hermite_trajectory(Y[:, i], np.zeros((1, 0, 2)), np.array([2.0]), 7, 4) for i in range(2)]
        assert exact_min_separation(flight, 2.0) == pytest.approx(expected, abs=1e-12)
        assert_same_checks(flight, boxes_around(rng, flight, (0.0, 0.1)), 0.5)


def test_ties_name_the_same_robot_and_step():
    """A formation: every robot flies the same path, so every limit is reached by every robot at once."""
    rng = np.random.default_rng(2)
    one = random_flight(rng, 1, 4, 0.0)[0]
    shift = np.zeros_like(one.coefficients)
    shift[:, 0, 0] = 3.0  # the constant coefficient: the same path 3 m to the side
    flight = [PiecewisePolynomial(one.durations, one.coefficients + i * shift) for i in range(6)]
    assert_same_checks(flight, boxes_around(rng, flight, (0.0, 0.1)), 0.5, (0.01, 0.01, 0.01))
    cert = certify(flight, flight[0].knots, boxes_around(rng, flight, (0.0, 0.1)), 0.5, (0.01, 0.01, 0.01))
    assert "robot 0's speed" in cert.problems[0]


def test_maxima_of_3d_flights_with_unequal_pieces():
    rng = np.random.default_rng(3)
    flights = [random_flight(rng, 1, int(rng.integers(1, 9)), 2.0, dim=3)[0] for _ in range(7)]
    for r in (0, 1, 2, 3, 8):  # 8 > degree: all zero
        assert max_derivative_norm_all(flights, r) == pytest.approx(ref.max_derivative_norm_all(flights, r), rel=1e-12)
        new = stacked_tau_coefficients(flights, r)
        old = np.concatenate([tr.derivative(r).tau_coefficients() for tr in flights])
        assert np.array_equal(new, old.transpose(1, 0, 2))  # bit for bit


def test_piece_stack_maps():
    rng = np.random.default_rng(4)
    flight = random_flight(rng, 5, 6, 3.0)
    c = stacked_tau_coefficients(flight)  # the common grid's shortcut
    assert np.array_equal(c, np.concatenate([tr.tau_coefficients() for tr in flight]).transpose(1, 0, 2))
    old = tau_control_points(np.concatenate([tr.tau_coefficients() for tr in flight]), 2, 4)
    matrix = control_point_matrix(7, 2, 4)
    assert np.array_equal(map_coefficients_in_order(matrix, c).transpose(1, 0, 2), old)  # the sums einsum forms
    np.testing.assert_allclose(map_coefficients(matrix, c).transpose(1, 0, 2), old, rtol=0, atol=1e-12)


def test_region_violation_is_the_einsum_sum():
    rng = np.random.default_rng(5)
    ang = rng.uniform(0, np.pi, (4, 7))
    axes = np.stack([np.stack([np.cos(ang), np.sin(ang)], -1), np.stack([-np.sin(ang), np.cos(ang)], -1)], axis=-2)
    axes[:, :3] = np.eye(2)  # boxes and oriented rectangles
    lower = rng.uniform(-1, 0, (4, 7, 2))
    regions = Regions(axes, lower, lower + rng.uniform(0.5, 2, (4, 7, 2)), np.zeros((4, 7), bool), 0.25)
    points = rng.normal(0, 1.5, (4, 7, 8, 2))
    points[:, :2] = lower[:, :2, None] + rng.uniform(0, 0.5, (4, 2, 8, 2))  # inside their boxes
    s = np.einsum("tnka,tnpa->tnpk", axes, points)
    viol = np.maximum(np.maximum(lower[:, :, None] - s, s - regions.upper[:, :, None]).max(axis=(-1, -2)), 0.0)
    assert np.array_equal(regions.violation(points), viol) and viol.max() > 0 and viol.min() == 0
