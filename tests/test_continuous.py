"""The continuous stage end to end: certified trajectories, seams, limits, exports, failures."""

import json
from functools import lru_cache
from pathlib import Path

import numpy as np
import pytest

import mrfswarm
import solvers
from mrfswarm.cli import main
from mrfswarm.pipeline import plan
from mrfswarm.safety import discrete_violations
from mrfswarm.receding_horizon import RecedingHorizon, TIME_LAW, chord_positions, safe_pruning
from mrfswarm.trajectory import CLOSED_FORM, PolylineReference, read_uav_csv, seam_jumps

EXP = Path(__file__).resolve().parents[1] / "experiments"
NO_SIM = ["simulation.enabled=false"]
QP_BACKENDS = [b for b in solvers.qp.available() if b != CLOSED_FORM][:2]  # osqp and one other


@lru_cache(maxsize=None)
def run(name: str, *overrides: str):
    return plan(mrfswarm.load_config(EXP / f"{name}.toml", NO_SIM + list(overrides)))


def independent_check(result, rate_hz=250.0):
    """Sample every robot at rate_hz: (min pairwise distance, any sample in an occupied cell)."""
    c = result.continuous
    t = np.linspace(0.0, c.makespan_s, int(c.makespan_s * rate_hz) + 1)
    pts = c.positions(t)
    iu, ju = np.triu_indices(pts.shape[1], 1)
    dmin = np.hypot(*(pts[:, iu] - pts[:, ju]).transpose(2, 0, 1)).min()
    grid = result.scenario.grid
    inside = ~grid.is_free(grid.world_to_cell(pts))
    return dmin, bool(inside.any())


@pytest.mark.parametrize("backend", QP_BACKENDS)
@pytest.mark.parametrize("name", ["corridor", "blocks", "free5"])
def test_end_to_end_is_certified(name, backend):
    r = run(name, f'smoothing.backend="{backend}"')
    c = r.continuous
    assert r.qp == backend
    if r.scenario.goal is not None:
        assert r.metrics.reached_goal
        end = c.positions(np.array([c.makespan_s]))[0]
        assert np.hypot(*(end.mean(axis=0) - r.scenario.goal_world)) <= r.config.scenario.goal_radius
    safety = r.config.smoothing.safety_distance * r.scenario.grid.resolution
    dmin, inside = independent_check(r)
    assert dmin >= safety - 1e-6 and not inside
    assert c.check.min_separation == pytest.approx(dmin, abs=0.02)
    sm = r.config.smoothing
    assert c.v_max <= sm.v_max * (1 + 1e-6) and c.a_max <= sm.a_max * (1 + 1e-6) and c.j_max <= sm.j_max * (1 + 1e-6)
    # every robot at rest at both ends, and on its start cell at t = 0
    for i, tr in enumerate(c.trajectories):
        for k in (1, 2, 3):
            assert np.abs(tr.evaluate(0.0, derivative=k)).max() < 1e-5
            assert np.abs(tr.evaluate(tr.duration, derivative=k)).max() < 1e-5
        np.testing.assert_allclose(tr.evaluate(0.0), r.discrete_paths_world()[0, i], atol=1e-6)


def test_references_keep_the_discrete_guarantee():
    """The pruned chords traversed with the common time law stay >= 1 cell apart (sampled)."""
    r = run("corridor10", "smoothing.enabled=false")
    paths = r.discrete.paths
    kept, _ = safe_pruning(paths, r.scenario.grid.free, 2)
    T = len(paths) - 1
    times = np.arange(T + 1, dtype=float)
    refs = [PolylineReference(chord_positions(paths[:, i], kept[i]), times, law=TIME_LAW) for i in range(paths.shape[1])]
    t = np.linspace(0, T, 40 * T + 1)
    pts = np.stack([f(t) for f in refs], axis=1)
    iu, ju = np.triu_indices(pts.shape[1], 1)
    assert np.hypot(*(pts[:, iu] - pts[:, ju]).transpose(2, 0, 1)).min() >= 1 - 1e-9
    assert any(len(k) < T + 1 for k in kept)  # something was pruned


def test_unsafe_chords_are_unpruned():
    """Robot 0's valid path (0,0)->(1,1)->(2,1)->(3,1) prunes to the chord (0,0)->(3,1), which
    passes 2/3 cell from robot 1 standing at (2,0) (though it crosses no trajectory): unsafe."""
    free = np.ones((8, 8), bool)
    r0 = [(0, 0), (1, 1), (2, 1), (3, 1)]
    paths = np.array([[a, (2, 0)] for a in r0])
    assert discrete_violations(paths, free) == []
    kept, unpruned = safe_pruning(paths, free, 3)
    assert unpruned == 1 and kept[0].tolist() == [0, 1, 2, 3]
    far = np.array([[a, (6, 6)] for a in r0])
    kept, unpruned = safe_pruning(far, free, 3)
    assert unpruned == 0 and kept[0].tolist() == [0, 3]


@pytest.mark.parametrize("seam", ["rest", "continuous"])
def test_seam_modes(seam):
    r = run("corridor", f'smoothing.seam="{seam}"')
    c = r.continuous
    execution_points = [c.knot_times[w.c] for w in c.windows if w.c < len(c.knot_times) - 1]
    assert len(execution_points) > 5
    for tr in c.trajectories:
        jumps = seam_jumps(tr, 3)  # (pieces - 1, 4): |jump| of derivatives 0..3 at each interior knot
        assert np.abs(jumps).max() < 1e-4
        speed = np.hypot(*tr.evaluate(np.array(execution_points), derivative=1).T)
        if seam == "rest":
            assert speed.max() < 1e-5  # the paper's stop-start at every execution point
    if seam == "continuous":
        allv = np.concatenate([np.hypot(*tr.evaluate(np.array(execution_points), derivative=1).T)
                               for tr in c.trajectories])
        assert allv.max() > 0.1  # the swarm does not stop at every execution point


def test_uav_csv_exports_evaluate_back(tmp_path):
    out = tmp_path / "out"
    rc = main(["run", str(EXP / "free5.toml"), "--out", str(out), "--set", "simulation.enabled=false"])
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
    assert res["min_separation_continuous"] >= 0.5 and res["achieved"]["v_max"] <= res["limits"]["v_max"]


def test_progress_is_quiet_off_a_terminal(tmp_path, capsys):
    main(["run", str(EXP / "free5.toml"), "--out", str(tmp_path / "o"), "--set", "simulation.enabled=false"])
    err = capsys.readouterr().err
    assert "MRF steps" not in err and "smoothing" not in err


@pytest.mark.parametrize("override, pattern", [
    ("smoothing.horizon=0", r"smoothing.horizon = 0: must be >= 1"),
    ("smoothing.execution=0", r"smoothing.execution = 0(\.0)?: must be in \(0, 1\]"),
    ("smoothing.execution=1.5", r"smoothing.execution = 1.5: must be in \(0, 1\]"),
    ('smoothing.seam="smooth"', r"smoothing.seam = 'smooth': must be one of rest, continuous"),
    ("smoothing.corridor=0.3", r"smoothing.corridor = 0.3"),
    ('smoothing.backend="nope"', r"unknown QP backend 'nope'"),
])
def test_bad_smoothing_settings(override, pattern, tmp_path, capsys):
    rc = main(["run", str(EXP / "free5.toml"), "--out", str(tmp_path / "o"), "--set", override])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1
    import re
    assert re.search(pattern, err[0]), err[0]


def test_limits_no_timing_can_meet_keep_the_discrete_outputs(tmp_path, capsys):
    out = tmp_path / "o"
    rc = main(["run", str(EXP / "free5.toml"), "--out", str(out), "--set", "simulation.enabled=false",
               "--set", "smoothing.v_max=1e-5"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "no timing meets v_max = 1e-05 m/s" in err[0] and str(out) in err[0]
    res = json.loads((out / "result.json").read_text())
    assert res["failure"] and res["mrf_steps"] > 0 and res["min_separation_continuous"] is None
    assert (out / "discrete_paths.csv").exists() and (out / "figures" / "discrete_paths.png").exists()


def test_a_swarm_that_cannot_move(tmp_path, capsys):
    cfg = tmp_path / "boxed.toml"
    cfg.write_text('[scenario]\nmap = { kind = "ascii", rows = ["#####....", "#.#.#....", "#####...."] }\n'
                   "start = { positions = [[1, 1], [3, 1]] }\ngoal = [7, 1]\n[interaction]\nk = 1\n"
                   '[goal_potential]\ndistance = "euclidean"\n')  # the geodesic field refuses this start earlier
    out = tmp_path / "o"
    rc = main(["run", str(cfg), "--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "the swarm cannot move" in err[0]
    assert json.loads((out / "result.json").read_text())["mrf_steps"] == 0


def test_receding_horizon_windows_cover_the_steps():
    r = run("corridor", "smoothing.enabled=false")
    for seam, H, E in [("rest", 4, 0.5), ("continuous", 4, 0.5), ("continuous", 6, 0.34), ("rest", 3, 1.0)]:
        cfg = r.config.smoothing.__class__(**{**r.config.smoothing.__dict__, "seam": seam, "horizon": H,
                                              "execution": E})
        rh = RecedingHorizon(r.discrete.paths, r.scenario.grid, cfg)
        wins = rh.windows()
        assert wins[0][0] == 0 and wins[-1][1] == r.discrete.n_steps
        for (a, c, b), (a2, _, _) in zip(wins, wins[1:]):
            assert a < c <= b and c == a2 and (b == c if seam == "rest" else b <= a + H)


def test_plans_in_threads_agree():
    """Compiled formulations are shared per shape; threads planning at once must not interfere."""
    import concurrent.futures as cf

    cfg = mrfswarm.load_config(EXP / "corridor.toml", NO_SIM)
    ref = plan(cfg).continuous
    t = np.linspace(0.0, ref.makespan_s, 400)
    with cf.ThreadPoolExecutor(4) as ex:
        outs = list(ex.map(lambda _: plan(cfg).continuous, range(4)))
    for c in outs:
        assert c.makespan_s == pytest.approx(ref.makespan_s)
        np.testing.assert_allclose(c.positions(t), ref.positions(t), atol=1e-6)
