"""Pieces that span several steps: the algebra, the certificate's split, the window rows, whole flights that fit a Crazyflie."""

import json
import logging

import numpy as np
import pytest

import mrfswarm
from mrfswarm.cli import main
from mrfswarm.config import SmoothingConfig, from_dict
from mrfswarm.continuous import RecedingHorizon, WindowFormulation
from mrfswarm.continuous.certificate import certify
from mrfswarm.continuous.formulation import hermite_trajectory, piece_maps
from mrfswarm.continuous.merge_pieces import (
    block_polynomial,
    block_sizes,
    merge_trajectories,
    merged_knots,
    project_blocks,
    restrict,
    restriction_matrix,
    step_pieces,
    window_pieces,
)
from mrfswarm.continuous.regions import Regions
from mrfswarm.errors import ConfigError
from mrfswarm.trajectory import PiecewisePolynomial, read_uav_csv
from mrfswarm.trajectory.bernstein import control_points, subdivision_matrix
from mrfswarm.trajectory.polynomial import derivative_row, tau_to_time
from support.passing import GRID, PASSING
from support.repository import EXPERIMENTS

#: cflib's Poly4D: 4 x 8 float32 coefficients and a float32 duration; a Crazyflie holds 4096 bytes of them.
PIECE_BYTES, MEMORY_BYTES = 4 * 8 * 4 + 4, 4096


def one_polynomial_flight(P, T):
    """A trajectory of one piece per step (durations ``T``) that is the polynomial ``P`` (tau-coefficients over the sum)."""
    c = restrict(P, T)
    return PiecewisePolynomial(T, tau_to_time(c, T))


# -- the algebra -----------------------------------------------------------------------------------


def test_restriction_is_de_casteljau_subdivision():
    """Restricting to [k/S, (k+1)/S] gives the control points the equal-part subdivision matrix gives."""
    rng = np.random.default_rng(0)
    c = rng.normal(size=(8, 2))
    tr = PiecewisePolynomial(np.array([1.0]), c[None])
    for S in (2, 4):
        parts = np.concatenate([control_points(PiecewisePolynomial(np.array([1.0]),
                                                                   (restriction_matrix(7, k / S, (k + 1) / S) @ c)[None]))[0]
                                for k in range(S)])
        np.testing.assert_allclose(parts, subdivision_matrix(7, S) @ control_points(tr)[0], atol=1e-12)
    np.testing.assert_array_equal(restriction_matrix(7, 0.0, 1.0), np.eye(8))


@pytest.mark.parametrize("degree, derivative", [(7, 4), (9, 4), (5, 3)])
def test_block_polynomial_recovers_the_polynomial_of_its_steps(degree, derivative):
    rng = np.random.default_rng(degree)
    P = rng.normal(size=(degree + 1, 2))
    T = np.array([0.3, 0.8, 0.5, 0.4])
    np.testing.assert_allclose(block_polynomial(restrict(P, T), T, derivative), P, atol=1e-9)


def test_block_polynomial_keeps_the_block_ends_exactly():
    """Step pieces that are not quite one polynomial: the fit keeps derivatives 0..q-1 of the block's two ends."""
    rng = np.random.default_rng(1)
    T = np.array([0.4, 0.6, 0.5])
    c = restrict(rng.normal(size=(8, 2)), T) + 1e-6 * rng.normal(size=(3, 8, 2))
    P = block_polynomial(c, T, 4)
    s = np.concatenate([[0.0], np.cumsum(T)]) / T.sum()
    for r in range(4):
        row0, row1 = derivative_row(7, r, 0.0), derivative_row(7, r, 1.0)
        np.testing.assert_allclose(row0 @ P * (s[1] - s[0]) ** r, row0 @ c[0], atol=1e-11)
        np.testing.assert_allclose(row1 @ P * (s[3] - s[2]) ** r, row1 @ c[2], atol=1e-11)


def test_block_sizes_and_window_pieces():
    assert block_sizes(4, 3).tolist() == [2, 1, 1] and block_sizes(4, 1).tolist() == [4]
    assert block_sizes(3, 5).tolist() == [1, 1, 1]
    assert merged_knots(np.array([2, 1]), 5).tolist() == [True, False, False, False]
    assert window_pieces(4, 20, 31) == 4  # the rest fits one piece per step: no merge
    assert window_pieces(4, 116, 31) == 1 and window_pieces(4, 37, 31) == 3


@pytest.mark.parametrize("steps", [1, 5, 31, 32, 37, 57, 116, 124, 130])
@pytest.mark.parametrize("execution", [1, 2, 4, 6])
def test_window_pieces_keep_a_flight_within_budget(steps, execution):
    """Every window merging as asked: within budget whenever one piece per window is (steps <= 31 windows)."""
    used, a = 0, 0
    while a < steps:
        flown = min(execution, steps - a)
        used += window_pieces(flown, steps - a, 31 - used)
        a += flown
    if -(-steps // execution) <= 31:
        assert used <= 31
    assert used == steps if steps <= 31 else used >= -(-steps // execution)


# -- the certificate on merged pieces ----------------------------------------------------------------


def _merged_pair():
    """Two robots, 4 steps; robot 0 flies steps 0..2 in one piece, robot 1 one piece per step. Regions: a box
    around each step's part of the curve, grown 5 cm."""
    rng = np.random.default_rng(3)
    T = np.array([0.8, 1.0, 0.9, 0.7])
    knots = np.concatenate([[0.0], np.cumsum(T)])
    P = rng.normal(0, 0.3, size=(8, 2)) + np.array([0.0, 0.0])
    steps0 = one_polynomial_flight(P, T[:3])
    last0 = PiecewisePolynomial(T[3:], np.concatenate([steps0.evaluate(knots[3])[None, None], np.zeros((1, 7, 2))], 1))
    robot0 = PiecewisePolynomial(np.concatenate([steps0.durations, T[3:]]),
                                 np.concatenate([steps0.coefficients, last0.coefficients]))
    merged0 = merge_trajectories([robot0], np.array([3, 1]), 4)[0]
    robot1 = PiecewisePolynomial(T, np.concatenate([np.tile([[5.0, 5.0]], (4, 1, 1)), np.zeros((4, 7, 2))], 1))
    split = step_pieces([merged0, robot1], knots)
    cps = np.stack([control_points(tr) for tr in split], axis=1)  # (4, 2, 8, 2)
    lo, hi = cps.min(axis=2) - 0.05, cps.max(axis=2) + 0.05
    regions = Regions(np.broadcast_to(np.eye(2), (4, 2, 2, 2)).copy(), lo, hi, np.zeros((4, 2), bool), 0.1)
    return [merged0, robot1], robot0, knots, regions


def test_merged_pieces_are_split_at_the_steps():
    (merged0, robot1), robot0, knots, regions = _merged_pair()
    assert merged0.pieces == 2 and robot1.pieces == 4
    split = step_pieces([merged0, robot1], knots)
    assert [tr.pieces for tr in split] == [4, 4]
    np.testing.assert_allclose(split[0].coefficients, robot0.coefficients, atol=1e-9)
    assert split[1] is robot1
    t = np.linspace(0, knots[-1], 777)
    np.testing.assert_allclose(split[0].evaluate(t), merged0.evaluate(t), atol=1e-12)
    assert "not end on the common time grid" in step_pieces([merged0], knots[[0, 1, 2, 4]] + [0, 0, 0.01, 0])
    assert "do not follow" in step_pieces([robot1], knots + 1e-6)


def test_the_certificate_splits_merged_pieces():
    flight, robot0, knots, regions = _merged_pair()
    cert = certify(flight, knots, regions, 0.2, (100.0, 100.0, 1000.0))
    assert cert.ok, cert.problems
    steps = certify([robot0, flight[1]], knots, regions, 0.2, (100.0, 100.0, 1000.0))  # the unmerged curves
    assert cert.near_pairs == steps.near_pairs and cert.separation_bound == pytest.approx(steps.separation_bound)
    np.testing.assert_allclose(cert.limit_bounds, steps.limit_bounds, rtol=1e-12)


def test_a_merged_piece_that_leaves_a_middle_step_region_is_caught():
    """The guard's violation: robot 0 flies steps 0..2 in one piece, and step 1's region holds where the piece
    is at the *start* of step 1's length, not where it is during step 1. Only splitting each step at its own
    times catches it (a split that restricts every step from its piece's start passes this flight: tried)."""
    T = np.array([0.8, 1.0, 0.9])
    knots = np.concatenate([[0.0], np.cumsum(T)])
    P = np.zeros((8, 2))
    P[1] = [3.0, 0.2]  # x = 3 sigma: forward all the way; y a small bulge
    P[2] = [0.0, -0.2]
    merged = PiecewisePolynomial(np.array([T.sum()]), tau_to_time(P[None], np.array([T.sum()])))
    hover = PiecewisePolynomial(T, np.concatenate([np.tile([[5.0, 5.0]], (3, 1, 1)), np.zeros((3, 7, 2))], 1))
    lo, hi = np.full((3, 2, 2), -50.0), np.full((3, 2, 2), 50.0)
    wrong = PiecewisePolynomial(np.array([T[1]]), (restriction_matrix(7, 0.0, T[1] / T.sum()) @ P)[None])
    cps = control_points(wrong)[0]
    lo[1, 0], hi[1, 0] = cps.min(axis=0) - 0.05, cps.max(axis=0) + 0.05
    regions = Regions(np.broadcast_to(np.eye(2), (3, 2, 2, 2)).copy(), lo, hi, np.zeros((3, 2), bool), 0.1)
    during = merged.evaluate(np.linspace(knots[1], knots[2], 201))
    assert (during[:, 0] > hi[1, 0, 0]).any()  # the robot really leaves step 1's region during step 1
    cert = certify([merged, hover], knots, regions, 0.2, (100.0, 100.0, 1000.0))
    assert not cert.ok and cert.problems[0].startswith("robot 0 leaves its region in step 1")


def test_merged_pieces_too_near_or_too_fast_in_one_step_are_caught():
    flight, _, knots, regions = _merged_pair()
    split = step_pieces(flight, knots)
    # robot 1 hovers where robot 0 flies in step 2: their relative hull in step 2 reaches the origin
    where = split[0].evaluate(0.5 * (knots[2] + knots[3]))
    hover = PiecewisePolynomial(np.diff(knots), np.concatenate([np.tile(where, (4, 1, 1)), np.zeros((4, 7, 2))], 1))
    big = Regions(regions.axes, np.full((4, 2, 2), -50.0), np.full((4, 2, 2), 50.0), regions.oriented, 0.1)
    cert = certify([flight[0], hover], knots, big, 0.2, (100.0, 100.0, 1000.0))
    assert not cert.ok and any("not proven apart in step 2" in p for p in cert.problems)
    speed = np.abs(control_points(split[0], 1)).max()
    cert = certify(flight, knots, big, 0.2, (0.5 * speed, 100.0, 1000.0))
    assert not cert.ok and any("speed" in p for p in cert.problems)


# -- the window problem ------------------------------------------------------------------------------



def test_taylor_rows_of_the_symbolic_piece():
    pm = piece_maps(7, 4)
    rng = np.random.default_rng(4)
    T = np.array([0.6, 1.7])
    Y = rng.normal(size=(3, 4, 2))
    traj = hermite_trajectory(Y, np.zeros((2, 0, 2)), T, 7, 4)
    k = pm.evaluate(T)
    for j in range(2):
        z = np.concatenate([Y[j], Y[j + 1]])
        a = np.arange(pm.nz)
        for end in (0, 1):
            for r in range(4, 8):
                row = k[pm.t_index(j, end, r, a)]
                t = traj.knots[j + end] + (-1e-12 if end else 1e-12)
                np.testing.assert_allclose(row @ z, traj.evaluate(t, derivative=r) / np.prod(np.arange(1, r + 1)),
                                           rtol=1e-6, atol=1e-6)


def test_a_merged_window_is_one_polynomial_per_block_and_certified():
    """Steps 0..3 of the crossing as one piece: the merge rows hold to the solver's tolerance, the projection
    makes them exact, and the window certifies. At the earlier 1.25 m/s cruise's witness durations (main's
    default grid makes them 2.42 s, where the projection moved a point 2.8e-5 m, past MERGED_MARGIN: such
    an attempt is refused by the certificate and the window falls back to more pieces)."""
    rh = RecedingHorizon(PASSING, GRID, SmoothingConfig(max_pieces=0, speed=1.25), 0.25)
    a, c, b = rh.windows()[0]
    merged = merged_knots(block_sizes(c - a, 1), b - a)
    start = np.zeros((rh.N, 4, 2))
    start[:, 0] = rh.X[0]
    form = WindowFormulation(rh._spec(a, b, np.arange(rh.N), start, np.flatnonzero(rh.seps.step < b), merged))
    import solvers.qp
    from mrfswarm.continuous.receding_horizon import QP_OPTIONS

    durations = rh.witness[a:b]
    sol = solvers.qp.solve(form.qp(durations), "piqp", QP_OPTIONS)
    Y, B = form.unpack(form.exact_ends(sol.x))
    Yp, Bp = project_blocks(Y, B, durations, merged, 7, 4)
    assert np.abs(Yp - Y).max() < 1e-4  # the solver met the merge rows (to its tolerance)
    np.testing.assert_array_equal(Yp[:, [0, 4, 5, 6, 7, 8]], Y[:, [0, 4, 5, 6, 7, 8]])  # block ends unchanged
    for g in range(rh.N):
        steps = hermite_trajectory(Yp[g], Bp[g], durations, 7, 4)
        one = merge_trajectories([steps], np.array([4, 1, 1, 1, 1]), 4)[0]
        t = np.linspace(0, durations.sum(), 999)
        np.testing.assert_allclose(one.evaluate(t), steps.evaluate(t), atol=1e-9)
    from mrfswarm.continuous.receding_horizon import _Solution

    assert rh._certify(_Solution(Yp, Bp, durations), a).ok


def test_max_pieces_is_checked():
    with pytest.raises(ConfigError, match="smoothing.max_pieces"):
        from_dict({"smoothing": {"max_pieces": -1}})
    assert SmoothingConfig().max_pieces == 31


# -- whole flights -----------------------------------------------------------------------------------

#: A 6 x 3.5 m arena in 0.25 m cells with three walls: 8 robots zig-zag through their gaps (77 MRF steps here; 38 with main's arrival rule).
WALLS = ((6, "top"), (12, "bottom"), (18, "top"))
ARENA_ROWS = ["".join("#" if any(x == w and (y >= 4 if side == "top" else y <= 9) for w, side in WALLS) else "."
                      for x in range(24)) for y in range(14)]
ARENA = {"scenario": {"map": {"kind": "ascii", "rows": ARENA_ROWS, "resolution": 0.25},
                      "start": {"positions": [[0.25 * x + 0.125, 0.25 * y + 0.125] for x in (1, 3) for y in (6, 8, 10, 12)]},
                      "goal": [5.5, 2.75], "goal_radius": 0.75, "robot_radius": 0.1},
         "smoothing": {"v_max": 1.0, "check_rate_hz": 500.0}, "simulation": {"enabled": False}}


@pytest.fixture(scope="module")
def arena():
    return mrfswarm.plan(from_dict(ARENA), progress=False)


def test_an_arena_flight_fits_a_crazyflie(arena, dense_check):
    r, c = arena, arena.continuous
    assert r.discrete.n_steps > 31 and r.metrics.reached_goal
    assert c.certificate.ok and c.pieces_fit
    assert max(c.pieces_per_robot) <= 31 and len(set(c.pieces_per_robot)) == 1
    assert max(c.pieces_per_robot) * PIECE_BYTES <= MEMORY_BYTES
    assert np.diff(c.piece_steps).max() > 1  # several steps per piece somewhere
    for tr in c.trajectories:  # one coarser grid for every robot, on the steps' knots
        np.testing.assert_allclose(tr.knots, c.knot_times[c.piece_steps], atol=1e-9)
    # the independent checks: 500 Hz in the plan and brute force here
    assert c.sampled is not None and c.sampled.in_obstacle is None
    assert c.sampled.min_separation >= 0.2 and c.sampled.min_clearance >= 0.1
    dense = dense_check(c.trajectories, r.scenario.grid, 500.0)
    assert dense["separation"] >= 0.2 and dense["clearance"] >= 0.1 and not dense["off_map"]
    assert c.v_max <= 1.0
    s = r.summary()
    assert s["pieces_per_robot"] == c.pieces_per_robot and s["piece_limit"]["fits"]
    assert [x["pieces"] for x in s["robots"]] == c.pieces_per_robot


def test_the_arena_flies_as_fast_as_one_piece_per_step(arena):
    """Merging only where the budget needs it costs no flight time here (same durations accepted)."""
    data = json.loads(json.dumps(ARENA))
    data["smoothing"]["max_pieces"] = 0
    data["smoothing"]["check_rate_hz"] = 0.0
    one = mrfswarm.plan(from_dict(data), progress=False).continuous
    assert one.pieces_per_robot == [arena.discrete.n_steps] * 8
    assert arena.continuous.makespan_s <= 1.05 * one.makespan_s


def test_exported_merged_pieces_keep_degree_7(tmp_path):
    out = tmp_path / "out"
    assert main(["run", str(EXPERIMENTS / "corridor.toml"), "--out", str(out), "--set", "simulation.enabled=false"]) == 0
    res = json.loads((out / "result.json").read_text())
    assert res["mrf_steps"] > 31 and max(res["pieces_per_robot"]) <= 31 and res["piece_limit"]["fits"]
    header = (out / "trajectories" / "robot_0.csv").read_text().splitlines()[0].split(",")
    assert header[1:9] == [f"x^{k}" for k in range(8)]
    r = mrfswarm.plan(mrfswarm.load_config(EXPERIMENTS / "corridor.toml", ["simulation.enabled=false"]))
    for i, tr in enumerate(r.continuous.trajectories):
        back = read_uav_csv(out / "trajectories" / f"robot_{i}.csv", dim=2)
        assert back.pieces == res["pieces_per_robot"][i] == tr.pieces and back.degree == 7
        t = np.linspace(0, tr.duration, 400)
        np.testing.assert_allclose(back.evaluate(t), tr.evaluate(t), atol=1e-9)


def test_a_flight_that_does_not_fit_is_reported(caplog):
    """Nine windows cannot fly in five pieces: the plan says so (result.json and a warning), it does not hide it."""
    with caplog.at_level(logging.WARNING, logger="mrfswarm.continuous.receding_horizon"):
        r = mrfswarm.plan(mrfswarm.load_config(EXPERIMENTS / "corridor.toml",
                                               ["simulation.enabled=false", "smoothing.max_pieces=5"]))
    c = r.continuous
    assert c.certificate.ok and not c.pieces_fit
    # a window flies one piece at least, so nine cannot fit five: no merging (it would only cost), one per step
    assert c.pieces_per_robot == [r.discrete.n_steps] * 5
    s = r.summary()["piece_limit"]
    assert s == {"max_pieces": 5, "fits": False, "robots_over": [0, 1, 2, 3, 4], "steps_per_piece_max": 1}
    assert "cannot fit smoothing.max_pieces = 5" in caplog.text and "does not fit" in caplog.text
    # what fewer windows would take: 33 steps in 5 windows fly 7 steps each, a horizon of 14 at execution 0.5
    assert "one piece per step, 33 per robot. Fitting needs fewer windows, smoothing.horizon >= 14 at execution 0.5" \
        in caplog.text
