"""The continuous stage end to end: certified flights, seams, limits, exports, failures."""

import json
import math
import re
from functools import cache

import numpy as np
import pytest

import mrfswarm
from mrfswarm.cli import main
from mrfswarm.config import SmoothingConfig
from mrfswarm.continuous import RecedingHorizon
from mrfswarm.continuous.merge_pieces import step_pieces
from mrfswarm.continuous.receding_horizon import WindowRecord
from mrfswarm.pipeline import plan
from mrfswarm.trajectory import read_uav_csv, seam_jumps
from mrfswarm.trajectory.bernstein import control_points
from support.attempts import unled
from support.repository import EXPERIMENTS

NO_SIM = ["simulation.enabled=false"]


@cache
def run(name: str, *overrides: str):
    return plan(mrfswarm.load_config(EXPERIMENTS / f"{name}.toml", NO_SIM + list(overrides)))


def full_stops(c, rate_hz=100.0, below=0.05):
    """Per robot: how many times its speed drops below ``below`` m/s and picks up again within the flight."""
    t = np.linspace(0.0, c.makespan_s, int(c.makespan_s * rate_hz) + 1)
    out = []
    for tr in c.trajectories:
        slow = np.linalg.norm(tr.evaluate(t, 1), axis=-1) < below
        edges = np.diff(slow.astype(int))
        starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
        out.append(int(sum(1 for s in starts if (ends > s).any())))
    return out


@pytest.mark.parametrize("backend", ["piqp", "proxsuite"])
@pytest.mark.parametrize("name", ["corridor", "blocks", "free5"])
def test_end_to_end_is_certified_and_checks_out_densely(name, backend, dense_check):
    r = run(name, f'smoothing.backend="{backend}"')
    c = r.continuous
    assert r.qp == backend and c.certificate.ok
    if r.scenario.goal is not None:
        assert r.metrics.reached_goal
        end = c.positions(np.array([c.makespan_s]))[0]
        assert np.hypot(*(end.mean(axis=0) - r.scenario.goal_world)) <= r.scenario.goal_radius
    radius = r.config.scenario.robot_radius
    dense = dense_check(c.trajectories, r.scenario.grid, 500.0)
    assert dense["separation"] >= 2 * radius and dense["clearance"] >= radius and not dense["off_map"]
    assert c.min_separation == pytest.approx(dense["separation"], abs=2e-3)  # exact vs 500 Hz
    assert c.certificate.separation_bound <= c.min_separation + 1e-12  # a lower bound
    sm = r.config.smoothing
    assert c.v_max <= sm.v_max and c.a_max <= sm.a_max and c.j_max <= sm.j_max
    assert c.certificate.limit_bounds[0] >= c.v_max - 1e-9  # control points bound the exact maxima
    for i, tr in enumerate(c.trajectories):  # at rest at both ends, on the start cell at t = 0
        for k in (1, 2, 3):
            assert np.abs(tr.evaluate(0.0, derivative=k)).max() < 1e-5
            assert np.abs(tr.evaluate(tr.duration, derivative=k)).max() < 1e-5
        np.testing.assert_allclose(tr.evaluate(0.0), r.discrete_paths_world()[0, i], atol=1e-6)
        # one common time grid: every step's knot, or every few steps' where a Crazyflie's 31 pieces need it
        np.testing.assert_allclose(tr.knots, c.knot_times[c.piece_steps], atol=1e-9)
        assert tr.pieces == c.pieces_per_robot[i] <= r.config.smoothing.max_pieces


def test_positions_at_one_time_are_robot_major():
    c = run("free5").continuous
    t = 0.37 * c.makespan_s
    one = c.positions(t)  # a number: (N, dim), robot i at row i, as at an array of one time
    assert one.shape == (len(c.trajectories), c.dim)
    np.testing.assert_array_equal(one, c.positions(np.array([t]))[0])
    np.testing.assert_array_equal(one[2], c.trajectories[2].evaluate(np.array([t]))[0])


@pytest.mark.parametrize("t", [float("nan"), np.array([0.0, np.inf])])
def test_positions_refuse_times_that_are_not_finite(t):
    """NaN gave NaN positions without a word (a library tour)."""
    with pytest.raises(ValueError, match="times must be finite"):
        run("free5").continuous.positions(t)


def test_positions_at_times_of_any_shape_end_in_robots_and_axes():
    """Times of shape (4, 3) gave positions of shape (4, N, 3, dim), the robots' axis between the times' (a library
    tour); a string ended in NumPy's "could not convert string to float"."""
    c = run("free5").continuous
    t = np.linspace(0.0, c.makespan_s, 12).reshape(4, 3)
    got = c.positions(t)
    assert got.shape == (4, 3, len(c.trajectories), c.dim)
    np.testing.assert_array_equal(got.reshape(12, len(c.trajectories), c.dim), c.positions(t.reshape(-1)))
    with pytest.raises(ValueError, match=r"^positions: times must be numbers \(s\), got 'a'$"):
        c.positions("a")


def test_corridor_flies_without_stopping():
    """The default (continuous seams, safe regions) flies the paper's corridor without a stop."""
    c = run("corridor").continuous
    assert full_stops(c) == [0] * 5
    assert full_stops(run("corridor", 'smoothing.seam="rest"', "smoothing.horizon=4").continuous)[0] > 5
    assert c.makespan_s < 35.0
    for tr in c.trajectories:  # continuous up to jerk at every knot, window seams included
        assert np.abs(seam_jumps(tr, 3)).max() < 1e-6


def test_rest_seams_stop_at_every_execution_point():
    c = run("corridor", 'smoothing.seam="rest"', "smoothing.horizon=4").continuous
    points = [c.knot_times[w.c] for w in c.windows if w.c < len(c.knot_times) - 1]
    assert len(points) > 5
    for tr in c.trajectories:
        assert np.hypot(*tr.evaluate(np.array(points), derivative=1).T).max() < 1e-5
        assert np.abs(seam_jumps(tr, 3)).max() < 1e-6


@pytest.mark.slow
def test_time_refinement_flies_faster(monkeypatch):
    # one piece per step: the refinement's own gain (merged windows keep their certified refinement too), over the
    # attempts it starts from: the default's leading attempt, which a refined run does not try, flies this corridor
    # 19.45 s, the refinement 19.49 (docs/flight_quality.md, "Twenty-seventh session")
    unled(monkeypatch)
    base = plan(mrfswarm.load_config(EXPERIMENTS / "corridor.toml", [*NO_SIM, "smoothing.max_pieces=0"])).continuous
    fast = run("corridor", "smoothing.time_refinement=true", "smoothing.max_pieces=0").continuous
    assert fast.certificate.ok and any(w.refined for w in fast.windows)
    # the default grid flies 22.4 s, refined 20.5 (a refined window never lasts longer than the QP's; merged 20.4)
    assert fast.makespan_s < 0.99 * base.makespan_s
    merged = run("corridor", "smoothing.time_refinement=true").continuous
    assert merged.certificate.ok and max(merged.pieces_per_robot) <= 31 and merged.makespan_s < base.makespan_s


def test_uav_csv_exports_evaluate_back(tmp_path):
    out = tmp_path / "out"
    rc = main(["run", str(EXPERIMENTS / "free5.toml"), "--out", str(out), "--set", "simulation.enabled=false"])
    assert rc == 0
    res = json.loads((out / "result.json").read_text())
    r = run("free5")
    t = np.linspace(0.0, res["makespan_s"], 500)
    for i in range(res["n_robots"]):
        tr = read_uav_csv(out / "trajectories" / f"robot_{i}.csv")
        assert tr.dim == 3
        np.testing.assert_allclose(tr.evaluate(t)[:, 2], r.config.scenario.altitude)
        np.testing.assert_allclose(tr.evaluate(t)[:, :2], r.continuous.trajectories[i].evaluate(t), atol=1e-9)
    header = (out / "trajectories" / "robot_0.csv").read_text().splitlines()[0]
    assert header.startswith("duration,x^0,") and header.endswith("yaw^7")
    for f in ("trajectories.png", "distances.png", "robot_xy.png"):
        assert (out / "figures" / f).stat().st_size > 5000
    assert res["certificate"]["ok"] and res["safety_distance_m"] == 0.5
    assert res["min_separation_continuous"] >= res["certificate"]["separation_lower_bound_m"] >= 0.5
    assert res["achieved"]["v_max"] <= res["limits"]["v_max"]


def test_progress_is_quiet_off_a_terminal(tmp_path, capsys):
    main(["run", str(EXPERIMENTS / "free5.toml"), "--out", str(tmp_path / "o"), "--set", "simulation.enabled=false"])
    err = capsys.readouterr().err
    assert "MRF steps" not in err and "smoothing" not in err


@pytest.mark.parametrize("override, pattern", [
    ("smoothing.horizon=0", r"smoothing.horizon = 0: must be >= 1"),
    ("smoothing.execution=0", r"smoothing.execution = 0(\.0)?: must be in \(0, 1\]"),
    ("smoothing.execution=1.5", r"smoothing.execution = 1.5: must be in \(0, 1\]"),
    ('smoothing.seam="smooth"', r"smoothing.seam = 'smooth': must be one of rest, continuous"),
    ("smoothing.corridor=0.3", r"config key smoothing.corridor was removed: .*smoothing.region_growth"),
    ("smoothing.safety_distance=0.5", r"smoothing.safety_distance was removed: .*scenario.robot_radius"),
    ("smoothing.region_growth=-1", r"smoothing.region_growth = -1(\.0)?: must be in \[0, 1000\]"),
    ("smoothing.check_rate_hz=50", r"smoothing.check_rate_hz = 50(\.0)?: must be 0 \(off\) or in \[100, 10000\]"),
    ("scenario.robot_radius=0.5", r"scenario.robot_radius = 0.5 m must be below half a cell \(0.5 m on this map; scenario\.map\.coarsen = 2 "
     r"draws it in 2 m cells\)"),
    ("scenario.robot_radius=0", r"scenario.robot_radius = 0(\.0)?: must be > 0"),
    ('smoothing.backend="nope"', r"error: smoothing\.backend: unknown QP backend 'nope'"),
])
def test_bad_smoothing_settings(override, pattern, tmp_path, capsys):
    rc = main(["run", str(EXPERIMENTS / "free5.toml"), "--out", str(tmp_path / "o"), "--set", override])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1
    assert re.search(pattern, err[0]), err[0]


def test_limits_no_timing_can_meet_keep_the_discrete_outputs(tmp_path, capsys):
    out = tmp_path / "o"
    rc = main(["run", str(EXPERIMENTS / "free5.toml"), "--out", str(out), "--set", "simulation.enabled=false",
               "--set", "smoothing.v_max=1e-5"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "no timing meets v_max = 1e-05 m/s" in err[0] and str(out) in err[0]
    res = json.loads((out / "result.json").read_text())
    assert res["failure"] and res["mrf_steps"] > 0 and res["min_separation_continuous"] is None
    assert (out / "discrete_paths.csv").exists() and (out / "figures" / "discrete_paths.png").exists()


def test_a_failed_plan_carries_what_was_computed():
    """After the discrete stage an error becomes a PlanError whose ``result`` holds the stages before."""
    from mrfswarm.errors import PlanError, UnsafeTrajectoryError

    with pytest.raises(PlanError, match="no timing meets v_max") as info:
        plan(mrfswarm.load_config(EXPERIMENTS / "free5.toml", ["simulation.enabled=false", "smoothing.v_max=1e-5"]))
    result = info.value.result
    assert isinstance(info.value.__cause__, UnsafeTrajectoryError)
    assert result.failure == str(info.value) and result.continuous is None and result.discrete.n_steps > 0
    assert result.pruned and result.summary()["failure"] == result.failure


def test_a_swarm_that_cannot_move(tmp_path, capsys):
    cfg = tmp_path / "boxed.toml"
    cfg.write_text('[scenario]\nmap = { kind = "ascii", rows = ["#####....", "#.#.#....", "#####...."] }\n'
                   "start = { positions = [[1, 1], [3, 1]] }\ngoal = [7, 1]\n[interaction]\nk = 1\n"
                   '[goal_potential]\ndistance = "euclidean"\n')  # the geodesic field refuses this start earlier
    out = tmp_path / "o"
    rc = main(["run", str(cfg), "--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "the swarm cannot move: icm found no move" in err[0]  # the method's finding
    assert json.loads((out / "result.json").read_text())["mrf_steps"] == 0


def test_receding_horizon_windows_cover_the_steps():
    r = run("corridor", "smoothing.enabled=false")
    for seam, H, E in [("rest", 4, 0.5), ("continuous", 4, 0.5), ("continuous", 6, 0.34), ("rest", 3, 1.0)]:
        cfg = SmoothingConfig(seam=seam, horizon=H, execution=E)
        wins = RecedingHorizon(r.discrete.paths, r.scenario.grid, cfg, 0.25).windows()
        assert wins[0][0] == 0 and wins[-1][1] == r.discrete.n_steps
        for (a, c, b), (a2, _, _) in zip(wins, wins[1:]):
            assert a < c <= b and c == a2 and (b == c if seam == "rest" else b <= a + H)


def test_a_solver_that_returns_garbage_is_caught_and_the_flight_stays_safe(monkeypatch):
    """Guard: every window is certified, not trusted. A QP backend returning a perturbed solution
    makes the windows fall back (down to the rest-to-rest witness), and the flight is still certified."""
    import solvers.qp

    real = solvers.qp.PreparedQP.solve

    def noisy(self, warm_start=None):  # every solve, set up afresh or updated in place (window_cache)
        sol = real(self, warm_start)
        x = sol.x + np.random.default_rng(len(sol.x)).normal(scale=2.0, size=sol.x.shape)
        return type(sol)(**{**sol.__dict__, "x": x})

    monkeypatch.setattr(solvers.qp.PreparedQP, "solve", noisy)
    r = plan(mrfswarm.load_config(EXPERIMENTS / "free5.toml", NO_SIM))
    c = r.continuous
    assert "witness" in {w.attempt for w in c.windows}
    failed = [f for w in c.windows for f in w.failed]
    assert any("not proven apart" in f or "leaves its region" in f or "control points reach" in f for f in failed)
    assert c.certificate.ok and c.min_separation >= 0.5


def test_plans_in_threads_agree():
    """Formulations and compiled pieces are shared; threads planning at once must not interfere."""
    import concurrent.futures as cf

    cfg = mrfswarm.load_config(EXPERIMENTS / "corridor.toml", NO_SIM)
    ref = plan(cfg).continuous
    t = np.linspace(0.0, ref.makespan_s, 400)
    with cf.ThreadPoolExecutor(4) as ex:
        outs = list(ex.map(lambda _: plan(cfg).continuous, range(4)))
    for c in outs:
        assert c.makespan_s == pytest.approx(ref.makespan_s)
        np.testing.assert_allclose(c.positions(t), ref.positions(t), atol=1e-6)


def test_control_points_stay_in_their_regions():
    r = run("blocks")
    c = r.continuous
    assert c.pieces_per_robot[0] < len(c.knot_times) - 1  # some pieces span several steps
    steps = step_pieces(c.trajectories, c.knot_times)  # each step's part of them: the regions are the steps'
    cps = np.stack([control_points(tr) for tr in steps], axis=1)  # (T, N, D+1, 2)
    assert c.regions.violation(cps).max() == 0.0


def test_a_discrete_move_that_cuts_a_corner_is_refused():
    """Guard: regions are checked against the map, so a discrete move closer than the radius to a wall stops the run."""
    from mrfswarm.errors import UnsafeTrajectoryError
    from mrfswarm.maps import OccupancyGrid

    occ = np.zeros((5, 4), bool)
    occ[1, 0] = True
    paths = np.array([[[0, 0]], [[2, 1]], [[3, 1]]])  # (0,0) -> (2,1) passes 0.22 cell from cell (1, 0)
    with pytest.raises(UnsafeTrajectoryError, match=r"robot 0's safe region in step 0 comes 0.\d+ m from an obstacle"):
        RecedingHorizon(paths, OccupancyGrid.from_occupied(occ), SmoothingConfig(), 0.25)


def test_plans_are_the_same_with_one_or_several_workers(monkeypatch):
    """Chunks of robots are packed the same way whatever the worker count, so a plan does not depend on it."""
    import mrfswarm.continuous.receding_horizon as rhm
    from mrfswarm.maps import OccupancyGrid

    monkeypatch.setattr(rhm, "PARALLEL_ROBOTS", 10)  # worker processes from 10 robots on (200 by default)
    monkeypatch.setattr(rhm, "CHUNK_ROBOTS", 8)  # several chunks per window
    block = np.array([[i, j] for i in range(6) for j in range(4)]) + 2
    paths = [block]
    for m in [(1, 0), (1, 1), (1, 0), (0, 1), (1, 1), (1, 0)]:
        paths.append(paths[-1] + m)
    grid = OccupancyGrid.from_occupied(np.zeros((16, 14), bool))
    plans = [RecedingHorizon(np.array(paths), grid, SmoothingConfig(), 0.25, workers=w).run() for w in (1, 2)]
    for a, b in zip(plans[0].trajectories, plans[1].trajectories):
        np.testing.assert_array_equal(a.durations, b.durations)
        np.testing.assert_allclose(a.coefficients, b.coefficients, rtol=0, atol=1e-9)
    assert plans[0].certificate.ok and max(w.rounds for w in plans[0].windows) >= 1


def test_chunks_are_alike_in_size_and_never_larger_than_asked(monkeypatch):
    """With chunks of up to 64 robots, 100 robots make two chunks of 50 (not 64 and 36: two workers would wait
    for the larger); with the default 12, nine chunks, none over 12."""
    import mrfswarm.continuous.receding_horizon as rhm

    single = [np.array([i]) for i in range(100)]
    sizes = [len(c) for c in rhm.pack_groups(single, rhm.chunk_size(100))]
    assert len(sizes) == 9 and max(sizes) <= rhm.CHUNK_ROBOTS == 12 and sum(sizes) == 100
    monkeypatch.setattr(rhm, "CHUNK_ROBOTS", 64)

    for n in range(1, 400):
        size = rhm.chunk_size(n)
        chunks = math.ceil(n / size)
        assert size <= rhm.CHUNK_ROBOTS and chunks == math.ceil(n / rhm.CHUNK_ROBOTS), n
        assert n - (chunks - 1) * size >= size - chunks, n  # the last chunk nearly full
    single = [np.array([i]) for i in range(100)]
    assert [len(c) for c in rhm.pack_groups(single, rhm.chunk_size(100))] == [50, 50]


def test_regions_and_corridors_keep_room_for_the_compressed_rounding():
    """EXPORT_SLACK: the plan keeps 3 mm inside every region and corridor (the certificate's bound on the
    separation says so), less where the cells leave less room around a robot."""
    from mrfswarm.continuous.certificate import certify
    from mrfswarm.continuous.receding_horizon import EXPORT_SLACK, RecedingHorizon
    from mrfswarm.maps import OccupancyGrid

    r = run("arena")  # robots a cell (0.25 m) apart, radius 0.1 m: near pairs in every step
    c, sm = r.continuous, r.config.smoothing
    assert c.certificate.near_pairs > 0 and max(c.pieces_per_robot) == len(c.knot_times) - 1
    # proven apart by the safety distance plus the slack (less a hair of solver tolerance)
    assert certify(c.trajectories, c.knot_times, c.regions, 0.2 + EXPORT_SLACK - 1e-5, (sm.v_max, sm.a_max, sm.j_max)).ok
    paths = np.array([[[0, 0], [4, 4]], [[1, 0], [4, 3]]])
    for res, radius, slack in ((1.0, 0.25, EXPORT_SLACK), (0.25, 0.124, 0.25 * (0.125 - 0.124))):
        grid = OccupancyGrid(np.zeros((6, 6)), resolution=res)
        assert RecedingHorizon(paths, grid, SmoothingConfig(), radius).slack == pytest.approx(slack)


def test_a_failing_attempt_stops_at_the_chunk_that_fails_and_solves_it_first_next_time(monkeypatch):
    """Two chunks, one of still robots (any durations do), one of moving robots that too short durations fail:
    an attempt solves chunks until that one fails, the next attempt solves it first and it alone; durations
    every chunk meets give the same solutions in either order."""
    import mrfswarm.continuous.receding_horizon as rhm
    from mrfswarm.maps import OccupancyGrid

    monkeypatch.setattr(rhm, "CHUNK_ROBOTS", 6)
    block = np.array([[3 * i, 3 * j] for i in range(4) for j in range(3)]) + 2  # 12 robots, 2 chunks, no pairs
    moving = np.arange(12) >= 6
    paths = np.array([block + k * np.array([1, 0]) * moving[:, None] for k in range(5)])
    grid = OccupancyGrid.from_occupied(np.zeros((20, 12), bool))
    rh = RecedingHorizon(paths, grid, SmoothingConfig(), 0.25, workers=1)
    calls = []
    real = rhm.solve_window
    monkeypatch.setattr(rhm, "solve_window", lambda spec, *a: calls.append(spec) or real(spec, *a))
    a, c, b = rh.windows()[0]
    start = rh._witness(a, b, rh.witness[a:b], None).Y[:, 0]
    rh.limit_rows[a:b] = True  # every limit row on: too short durations are infeasible for the moving robots
    still_first = None
    for attempt in range(3):
        calls.clear()
        if attempt == 2:  # the still chunk first: the attempt still stops at the moving one, having solved both
            rh._hard[:] = ~moving
        sol, why = rh._solve(a, b, start, np.full(b - a, 0.05), WindowRecord(a=a, c=c, b=b))
        assert sol is None and "6 robots" in why, (attempt, why)
        np.testing.assert_array_equal(rh._hard, moving)  # the chunk that failed
        solved_moving = [not np.allclose(spec.end, spec.start[:, 0]) for spec in calls]
        assert solved_moving[-1] and not any(solved_moving[:-1]), (attempt, solved_moving)  # stopped there
        if attempt == 0:
            still_first = len(calls) == 2
        else:
            assert len(calls) == (1 if attempt == 1 else 2), (attempt, len(calls))
    assert still_first is not None
    good = rh.witness[a:b]
    first, _ = rh._solve(a, b, start, good, WindowRecord(a=a, c=c, b=b))
    rh._hard[:] = ~rh._hard  # the other chunk first
    second, _ = rh._solve(a, b, start, good, WindowRecord(a=a, c=c, b=b))
    np.testing.assert_array_equal(first.Y, second.Y)


def _slow_task(k: int, folder: str):
    """A chunk's stand-in for the pool: the first fails at once, the others take a while and leave a mark."""
    import pathlib
    import time

    if k == 0:
        return "failed"
    time.sleep(0.5)
    (pathlib.Path(folder) / f"ran{k}").touch()
    return k


def test_the_workers_do_not_start_chunks_queued_behind_a_failure(tmp_path):
    """In the worker processes, the calls not yet started when one fails are cancelled: one worker, eight calls,
    the first failing at once: the last three never run (the pool hands a worker's queue up to two calls ahead,
    so the next three may have started before the failure comes back; each takes half a second)."""
    from mrfswarm.maps import OccupancyGrid
    from mrfswarm.pools import process_pool

    paths = np.array([[[2, 2]], [[3, 2]]])
    rh = RecedingHorizon(paths, OccupancyGrid.from_occupied(np.zeros((6, 6), bool)), SmoothingConfig(), 0.25)
    with process_pool(1) as pool:
        rh._pool = pool
        out = rh._map(_slow_task, [(k, str(tmp_path)) for k in range(8)])
    rh._pool = None
    assert out[0] == "failed" and out[5:] == [None] * 3, out
    assert not any((tmp_path / f"ran{k}").exists() for k in (5, 6, 7))
    # without a failure every call runs, results in order
    with process_pool(2) as pool:
        rh._pool = pool
        assert rh._map(_slow_task, [(k, str(tmp_path)) for k in (1, 2, 3)]) == [1, 2, 3]
    rh._pool = None
