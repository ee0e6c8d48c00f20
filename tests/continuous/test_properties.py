"""Safety of the continuous stage on random and adversarial swarms, checked by dense sampling (500 Hz).

Every flight must be certified, and an independent brute-force check at 500 Hz must find
separation >= 2 x radius, clearance >= radius, nothing off the map, control points in
their regions and the exact maxima of v, a, j within the limits.
"""

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from mrfswarm.config import SmoothingConfig, from_dict
from mrfswarm.continuous import RecedingHorizon
from mrfswarm.continuous.sampled_check import min_pair_distance
from mrfswarm.discrete.safety import discrete_violations
from mrfswarm.errors import ScenarioError
from mrfswarm.maps import OccupancyGrid
from mrfswarm.pipeline import plan
from mrfswarm.trajectory import max_derivative_norms
from mrfswarm.trajectory.bernstein import control_points


def assert_safe(c, grid, radius, limits, dense_check, rate_hz=500.0):
    assert c.certificate.ok, c.certificate.problems
    d = dense_check(c.trajectories, grid, rate_hz)
    assert d["separation"] >= 2 * radius - 1e-9, d
    assert d["clearance"] >= radius - 1e-9 and not d["off_map"], d
    cps = np.stack([control_points(tr) for tr in c.trajectories], axis=1)
    assert c.regions.violation(cps).max() == 0.0
    for r, lim in zip((1, 2, 3), limits):
        assert max_derivative_norms(c.trajectories, r).max() <= lim


def fly(paths, occupied, radius=0.25, resolution=1.0, **smoothing):
    grid = OccupancyGrid.from_occupied(occupied, resolution=resolution)
    assert discrete_violations(np.asarray(paths), grid.free) == []
    cfg = SmoothingConfig(**smoothing)
    return RecedingHorizon(np.asarray(paths), grid, cfg, radius).run(), grid, (cfg.v_max, cfg.a_max, cfg.j_max)


@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 10_000), n=st.integers(3, 8))
def test_random_maps_and_swarms(seed, n, dense_check):
    """Random obstacles, a packed random swarm, a random goal: the whole pipeline."""
    rng = np.random.default_rng(seed)
    W, H = 18, 14
    occ = np.zeros((W, H), bool)
    for _ in range(4):
        x, y = rng.integers(6, W - 2), rng.integers(0, H - 2)
        occ[x:x + rng.integers(1, 3), y:y + rng.integers(1, 4)] = True
    side = int(np.ceil(np.sqrt(n)))
    start = [[1 + (i % side), 2 + (i // side)] for i in range(n)]
    occ[:side + 2, :] = False
    goal = [int(rng.integers(W - 4, W)), int(rng.integers(0, H))]
    occ[goal[0], goal[1]] = False
    rows = ["".join("#" if occ[x, y] else "." for x in range(W)) for y in range(H)]
    cfg = from_dict({"scenario": {"map": {"kind": "ascii", "rows": rows}, "start": {"positions": start},
                                  "goal": goal}, "interaction": {"k": min(3, n - 1)}, "mrf": {"max_steps": 30},
                     "simulation": {"enabled": False}})
    try:
        r = plan(cfg)
    except ScenarioError:
        assume(False)  # a swarm that cannot move at all: nothing to smooth
    assert_safe(r.continuous, r.scenario.grid, 0.25, (2.0, 4.0, 4.0), dense_check)


def test_column_through_a_one_cell_corridor(dense_check):
    """Robots following each other nose to tail (A: 0 -> 1 while B: 1 -> 2) down a corridor one cell wide."""
    occ = np.ones((14, 3), bool)
    occ[:, 1] = False
    xs = [[2, 1, 0]] + [[2 + t, 1 + t, t] for t in range(1, 9)] + [[10, 9, 8]] * 2 + [[11, 10, 9]]
    paths = [[[x, 1] for x in row] for row in xs]
    c, grid, limits = fly(paths, occ)
    assert_safe(c, grid, 0.25, limits, dense_check)
    assert c.min_separation < 1.0  # they do close up within the step (the discrete plan keeps one cell)


def test_packed_block_turning(dense_check):
    """A 3 x 3 block one cell apart moving diagonally, then straight, then turning."""
    moves = [(1, 1)] * 4 + [(1, 0)] * 3 + [(0, 1)] * 3
    block = np.array([[i, j] for i in range(3) for j in range(3)]) + 1
    paths = [block]
    for m in moves:
        paths.append(paths[-1] + m)
    c, grid, limits = fly(np.array(paths), np.zeros((14, 14), bool))
    assert_safe(c, grid, 0.25, limits, dense_check)


def test_two_robots_swap_ends(dense_check):
    """A and B exchange their start cells, passing each other in a corridor three cells wide."""
    A = [(0, 1), (1, 0), (2, 0), (3, 0), (4, 0), (5, 0), (6, 1)]
    B = [(6, 1), (5, 2), (4, 2), (3, 2), (2, 2), (1, 2), (0, 1)]
    occ = np.ones((7, 5), bool)
    occ[:, :3] = False
    c, grid, limits = fly([[a, b] for a, b in zip(A, B)], occ)
    assert_safe(c, grid, 0.25, limits, dense_check)


@pytest.mark.parametrize("resolution, radius", [(2.0, 0.6), (0.5, 0.2)])
def test_more_than_64_robots_at_other_resolutions(resolution, radius, dense_check):
    """70 robots in a packed block (the sampled checks' k-d tree branch), on maps of 2 m and 0.5 m cells."""
    block = np.array([[i, j] for i in range(10) for j in range(7)]) + 2
    paths = [block]
    for m in [(1, 0), (1, 1), (1, 1), (0, 1), (1, 0)]:
        paths.append(paths[-1] + m)
    occ = np.zeros((20, 16), bool)
    occ[15:, :3] = True  # an obstacle the block passes near
    c, grid, limits = fly(np.array(paths), occ, radius=radius, resolution=resolution, check_rate_hz=500.0)
    assert_safe(c, grid, radius, limits, dense_check)
    assert c.min_separation >= 2 * radius and c.min_separation < resolution  # in metres, not cells
    assert c.sampled.min_separation == pytest.approx(c.min_separation, abs=1e-3)


@pytest.mark.parametrize("d", [2, 3])
def test_pair_distance_kd_tree_branch_matches_brute_force(d):
    rng = np.random.default_rng(7)
    for n in (10, 65, 200):
        pts = np.cumsum(rng.normal(scale=0.05, size=(300, n, d)), axis=0) + rng.uniform(0, 15, (1, n, d))
        dmin, pairs = min_pair_distance(pts)
        iu, ju = np.triu_indices(n, 1)
        brute = np.linalg.norm(pts[:, iu] - pts[:, ju], axis=-1)
        np.testing.assert_allclose(dmin, brute.min(axis=1), rtol=0, atol=1e-12)
        got = np.linalg.norm(pts[np.arange(300), pairs[:, 0]] - pts[np.arange(300), pairs[:, 1]], axis=-1)
        np.testing.assert_allclose(got, dmin, atol=1e-12)

