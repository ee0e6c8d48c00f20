"""`mrfswarm run`: outputs of the discrete stage, and one-line errors for bad input."""

import csv
import json
import os
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from mrfswarm.cli import main
from support.repository import EXPERIMENTS, ROOT

CORRIDOR_MAP = """map = { kind = "boxes", size = [40, 40], boxes = [
    { center = [19.5, 32.5], size = [18, 16] }, { center = [19.5, 9.5], size = [18, 16] }] }"""


def write_config(tmp_path: Path, body: str) -> Path:
    p = tmp_path / "c.toml"
    p.write_text(body)
    return p


def test_run_discrete_outputs(tmp_path):
    out = tmp_path / "out"
    rc = main(["run", str(EXPERIMENTS / "corridor.toml"), "--out", str(out), "--set", "smoothing.enabled=false"])
    assert rc == 0
    res = json.loads((out / "result.json").read_text())
    for key in ("n_robots", "mrf_steps", "converged", "reached_goal", "swarm_energy", "min_separation_discrete",
                "min_separation_continuous", "min_obstacle_clearance", "makespan_s", "mrf", "qp", "timings_s"):
        assert key in res, key
    assert res["n_robots"] == 5 and res["mrf"] == "icm" and res["reached_goal"] is True
    assert res["min_separation_discrete"] >= 1.0 - 1e-9
    assert len(res["swarm_energy"]) == res["mrf_steps"] + 1
    rows = list(csv.DictReader(open(out / "discrete_paths.csv")))
    assert list(rows[0]) == ["step", "robot", "x", "y", "z"]
    assert len(rows) == (res["mrf_steps"] + 1) * 5
    first = {int(r["robot"]): (float(r["x"]), float(r["y"])) for r in rows if r["step"] == "0"}
    assert first == {0: (4, 16), 1: (4, 18), 2: (4, 20), 3: (4, 22), 4: (4, 24)}
    assert {float(r["z"]) for r in rows} == {res["config"]["scenario"]["altitude"]}  # a 2-D run flies at its altitude
    for f in ("discrete_paths.png", "swarm_energy.png", "pruned_paths.png"):
        assert (out / "figures" / f).stat().st_size > 5000


def test_set_mrf_and_seed_flags(tmp_path):
    out = tmp_path / "o"
    rc = main(["run", str(EXPERIMENTS / "free5.toml"), "--out", str(out), "--mrf", "exact", "--seed", "3",
               "--set", "smoothing.enabled=false", "--set", "mrf.max_steps=4"])
    assert rc == 0
    res = json.loads((out / "result.json").read_text())
    assert res["mrf"] == "exact" and res["mrf_steps"] <= 4 and res["config"]["mrf"]["max_steps"] == 4


def test_a_seed_is_recorded_where_it_acts_and_the_recorded_config_plans_the_same(tmp_path):
    # --seed overrides the sampled start's seed and the MRF method's: result.json's config must say so, or the
    # run cannot be reproduced from its own output
    from mrfswarm import pipeline
    from mrfswarm.config import from_dict, load_config

    out = tmp_path / "o"
    rc = main(["run", str(EXPERIMENTS / "free5.toml"), "--out", str(out), "--mrf", "gibbs", "--seed", "3",
               "--set", "smoothing.enabled=false"])
    assert rc == 0
    res = json.loads((out / "result.json").read_text())
    assert res["config"]["scenario"]["start"]["seed"] == 3 and res["config"]["mrf"]["options"]["seed"] == 3
    discrete = load_config(EXPERIMENTS / "free5.toml", ["smoothing.enabled=false"])
    seeded = pipeline.plan(discrete, mrf="gibbs", seed=3, progress=False).discrete.paths
    again = pipeline.plan(from_dict(res["config"]), progress=False).discrete.paths
    assert np.array_equal(again, seeded)
    unseeded = pipeline.plan(discrete, mrf="gibbs", progress=False).discrete.paths
    assert not np.array_equal(unseeded, seeded)  # the seed did act


BAD = {
    "robot in wall": (f"[scenario]\n{CORRIDOR_MAP}\nstart = {{ positions = [[4, 16], [20, 30]] }}\ngoal = [35, 20]\n"
                      "[interaction]\nk = 1\n",
                      r"error: scenario\.start\.positions\[1\]: robot 1 at \(20, 30\) is inside an obstacle"),
    "robot off map": ("[scenario]\nmap = { kind = \"free\", size = [10, 10] }\nstart = { positions = [[1, 1], [12, 3]] }\n"
                      "[interaction]\nk = 1\n",
                      r"error: scenario\.start\.positions\[1\]: robot 1 at \(12, 3\) is off the map"),
    # numpy's "invalid value encountered in cast" was printed beside the error (a tour)
    "robot far off map": ("[scenario]\nmap = { kind = \"free\", size = [10, 10] }\n"
                          "start = { positions = [[1, 1e300], [2, 3]] }\n[interaction]\nk = 1\n",
                          r"error: scenario\.start\.positions\[0\]: robot 0 at \(1, 1e\+300\) is off the map"),
    "goal in wall": (f"[scenario]\n{CORRIDOR_MAP}\nstart = {{ positions = [[4, 16], [4, 18]] }}\ngoal = [20, 30]\n"
                     "[interaction]\nk = 1\n", r"scenario.goal \(20, 30\) is inside an obstacle"),
    "two in one cell": ("[scenario]\nmap = { kind = \"free\", size = [10, 10] }\n"
                        "start = { positions = [[1, 1], [2.2, 1], [1.9, 0.8]] }\n[interaction]\nk = 1\n",
                        r"error: scenario\.start\.positions: robots 1 and 2 are both in cell \(2, 1\)"),
    "k < 1": ("[interaction]\nk = 0\n", r"interaction.k = 0"),
    "k >= N": ("[scenario]\nstart = { positions = [[1, 1], [3, 3], [5, 5]] }\n[interaction]\nk = 3\n",
               r"interaction.k = 3: must satisfy 1 <= k < N = 3"),
    "morse": ("[interaction]\nk_a = 3.0\n", r"interaction.k_a = 3.0: must be > interaction.k_r = 4.0"),
    "morse ratio": ("[interaction]\na = 0.5\nb = 0.9\nk_a = 6.0\nk_r = 4.0\n", r"b \* k_r / \(a \* k_a\) = 1\.2"),
    "unknown key": ("[mrf]\nordr = 2\n", r"unknown config key mrf.ordr"),
    "unknown section": ("[mfr]\norder = 2\n", r"unknown config section 'mfr'"),
    "bad type": ("[mrf]\norder = \"two\"\n", r"mrf.order must be an integer, got 'two'"),
    "malformed map": ("[scenario]\nmap = { kind = \"movingai\", path = \"bad.map\" }\n", r"bad.map"),
    "missing map": ("[scenario]\nmap = { kind = \"ros\", path = \"nowhere.yaml\" }\n", r"nowhere.yaml"),
    "unknown mrf": ("", r"error: mrf\.method: unknown MRF method 'nope'"),
    "bad toml": ("[mrf\norder = 2\n", r"invalid TOML"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_input_is_one_line_exit_2(case, tmp_path, capsys):
    body, pattern = BAD[case]
    (tmp_path / "bad.map").write_text("type octile\nheight 2\nwidth 3\nmap\n...\n..\n")
    cfg = write_config(tmp_path, body)
    out = tmp_path / "out"
    argv = ["run", str(cfg), "--out", str(out)] + (["--mrf", "nope"] if case == "unknown mrf" else [])
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)  # a numpy warning printed beside the error is a second line
        rc = main(argv)
    err = capsys.readouterr().err
    assert rc == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("mrfswarm: error: "), err
    import re
    assert re.search(pattern, lines[0]), lines[0]
    assert not (out / "result.json").exists()


def test_bad_input_from_a_real_process_has_no_traceback(tmp_path):
    cfg = write_config(tmp_path, BAD["robot in wall"][0])
    p = subprocess.run([sys.executable, "-m", "mrfswarm.cli", "run", str(cfg), "--out", str(tmp_path / "o")],
                       capture_output=True, text=True)
    assert p.returncode == 2
    assert "Traceback" not in p.stderr and len(p.stderr.strip().splitlines()) == 1
    assert "inside an obstacle" in p.stderr


def test_python_dash_m_mrfswarm_is_the_command():
    """`python -m mrfswarm solvers` said "No module named mrfswarm.__main__; 'mrfswarm' is a package and cannot be
    directly executed" (only `python -m mrfswarm.cli` worked), where the console script is not on the PATH."""
    p = subprocess.run([sys.executable, "-m", "mrfswarm", "solvers"], capture_output=True, text=True, cwd=ROOT)
    assert p.returncode == 0, p.stderr
    assert "NLP backends (--nlp)" in p.stdout and "MRF methods (--mrf)" in p.stdout


def test_missing_config_file(capsys):
    assert main(["run", "/no/such/config.toml"]) == 2
    assert "cannot read config '/no/such/config.toml'" in capsys.readouterr().err


@pytest.mark.parametrize("command", [["run"], ["sweep", "--grid", "interaction.k=2,3"]])
def test_a_config_that_is_not_utf8_text_is_one_line(command, tmp_path, capsys):
    cfg = tmp_path / "binary.toml"
    cfg.write_bytes(b"\xff\xfe[scenario]\n")
    assert main([command[0], str(cfg), *command[1:], "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "cannot read config" in err[0] and "not UTF-8 text (byte 0)" in err[0], err
    assert not (tmp_path / "o").exists()


def test_discrete_paths_csv_matches_result(tmp_path):
    out = tmp_path / "out"
    main(["run", str(EXPERIMENTS / "free5.toml"), "--out", str(out), "--set", "smoothing.enabled=false"])
    data = np.loadtxt(out / "discrete_paths.csv", delimiter=",", skiprows=1)
    res = json.loads((out / "result.json").read_text())
    assert data.shape[1] == 5  # step, robot, x, y, z
    last = data[data[:, 0] == res["mrf_steps"]][:, 2:]
    d = np.linalg.norm(last[:, None] - last[None], axis=-1)
    np.fill_diagonal(d, np.inf)
    assert d.min() >= 1.0


def test_the_nlp_flag_reaches_the_time_refinement(tmp_path, monkeypatch):
    """``--nlp lbfgsb`` with the refinement on: every NLP the continuous stage solves goes to L-BFGS-B,
    the refinement is kept in some window, the plan is certified and says which backend refined it."""
    import solvers.nlp

    calls: list[str] = []
    minimize = solvers.nlp.minimize

    def spy(problem, backend=solvers.nlp.DEFAULT_BACKEND, options=None):
        calls.append(backend)
        return minimize(problem, backend, options)

    monkeypatch.setattr(solvers.nlp, "minimize", spy)
    out = tmp_path / "out"
    # time_weight 1000 (default 10): below it the windows' optimum of snap + weight x time lies at longer steps
    # than the ones flown (at 100 the gradient of f in the first window's steps is about -2700), which the
    # refinement does not take, so it would keep no window here. (At 100 it once "kept" the QP's own point,
    # re-solved 1e-7 lower: the refinement now starts from the QP's solution itself, so the flight must be shorter.)
    common = [str(EXPERIMENTS / "free5.toml"), "--set", "simulation.enabled=false", "--set", "smoothing.time_weight=1000"]
    rc = main(["run", *common, "--out", str(out), "--set", "smoothing.time_refinement=true", "--nlp", "lbfgsb"])
    res = json.loads((out / "result.json").read_text())
    assert rc == 0 and calls and set(calls) == {"lbfgsb"}
    assert res["nlp"] == "lbfgsb" and res["config"]["smoothing"]["nlp"] == "lbfgsb"
    assert res["certificate"]["ok"] and res["refined_windows"] >= 1
    assert main(["run", *common, "--out", str(tmp_path / "plain")]) == 0
    plain = json.loads((tmp_path / "plain" / "result.json").read_text())
    assert res["makespan_s"] < plain["makespan_s"] - 0.01


def _crashing(problem, options):
    """L-BFGS-B whose native part dies at its fourth evaluation: a backend that raises in the middle of a solve."""
    import dataclasses

    from solvers.nlp import lbfgsb_

    calls = 0

    def fun(x):
        nonlocal calls
        calls += 1
        if calls > 3:
            raise RuntimeError("the native library crashed")
        return problem.fun(x)

    return lbfgsb_.solve(dataclasses.replace(problem, fun=fun), options)


def test_an_nlp_backend_that_raises_leaves_its_windows_unrefined_and_says_so(tmp_path, capsys):
    """The refinement only shortens a certified flight: a backend that raised aborted the whole run (exit 2), where
    a QP backend's failure flies the window's witness. Now the run goes on, certified, and one line says why."""
    import solvers.nlp
    from solvers.registry import Backend

    record = Backend(name="crashing", entry=_crashing, capabilities=solvers.nlp.BACKENDS.get("lbfgsb").capabilities)
    common = [str(EXPERIMENTS / "free5.toml"), "--set", "simulation.enabled=false", "--set", "smoothing.time_weight=1000"]
    solvers.nlp.BACKENDS.register(record)
    try:
        rc = main(["run", *common, "--out", str(tmp_path / "out"), "--set", "smoothing.time_refinement=true",
                   "--nlp", "crashing"])
    finally:
        solvers.nlp.BACKENDS.unregister("crashing")
    err = capsys.readouterr().err
    res = json.loads((tmp_path / "out" / "result.json").read_text())
    assert rc == 0 and res["certificate"]["ok"] and res["nlp"] == "crashing"
    assert res["refinement_errors"] == ["crashing failed: RuntimeError: the native library crashed"]
    assert "warning: the time refinement's NLP backend raised: crashing failed: RuntimeError: the native library " \
           "crashed;" in err
    assert main(["run", *common, "--out", str(tmp_path / "plain")]) == 0
    plain = json.loads((tmp_path / "plain" / "result.json").read_text())
    assert plain["refinement_errors"] == [] and res["makespan_s"] <= plain["makespan_s"] + 1e-9


def test_the_run_line_reports_the_flight_against_its_lower_bound(tmp_path, capsys):
    """A smoothed run prints its makespan over the lower bound and its stops per robot, as result.json has them."""
    import re

    rows = ", ".join(f'"{"." * 15}{"." if 9 <= y <= 11 else "@"}{"." * 14}"' for y in range(20))
    cfg = write_config(tmp_path, f"[scenario]\nmap = {{ kind = \"ascii\", rows = [{rows}] }}\n"
                                 "start = { center = [6, 10], n_robots = 5, sigma = 1.0, seed = 0 }\ngoal = [25, 10]\n"
                                 "[interaction]\nk = 3\n[simulation]\nenabled = false\n")
    out = tmp_path / "out"
    assert main(["run", str(cfg), "--out", str(out)]) == 0
    line = capsys.readouterr().out
    m = re.search(r"makespan ([\d.]+) s \(([\d.]+) x the lower bound, ([\d.]+) stops per robot\)", line)
    assert m, line
    q = json.loads((out / "result.json").read_text())["flight_quality"]
    assert float(m[2]) == pytest.approx(q["makespan_over_bound"], abs=0.005) and q["makespan_over_bound"] > 1
    assert float(m[3]) == pytest.approx(q["stops_per_robot"], abs=0.005)


def test_a_swarm_that_starts_at_the_goal_plans_a_hover(tmp_path):
    # every robot inside the goal region from the start: the discrete plan has no step, and the continuous
    # stage (regions, separations, certificate, exports) must still give a complete, certified run
    cfg = write_config(tmp_path, "[scenario]\nmap = { kind = \"free\", size = [20, 20] }\n"
                       "start = { positions = [[16, 10], [17, 10], [18, 10], [17, 9], [17, 11]] }\ngoal = [17, 10]\n")
    out = tmp_path / "out"
    assert main(["run", str(cfg), "--out", str(out), "--workers", "1", "--set", "simulation.enabled=false"]) == 0
    res = json.loads((out / "result.json").read_text())
    assert res["mrf_steps"] == 0 and res["complete"] is True and res["certificate"]["ok"] is True
    assert res["flight_quality"]["stops_per_robot"] == 0.0
    assert (out / "crazyflie").is_dir() and (out / "trajectories").is_dir()


def test_windows_that_fly_the_rest_to_rest_witness_are_said(tmp_path, capsys):
    """A QP budget too small for any window (max_iter = 1): every window falls back to the certified rest-to-rest
    witness. The run is safe and complete, but it flies with stops: one warning line says so."""
    free5 = ["--set", "simulation.enabled=false", "--set", "mrf.max_steps=6"]
    assert main(["run", str(EXPERIMENTS / "free5.toml"), "--out", str(tmp_path / "ok"), *free5]) == 0
    assert "witness" not in capsys.readouterr().err
    out = tmp_path / "tight"
    assert main(["run", str(EXPERIMENTS / "free5.toml"), "--out", str(out), *free5,
                 "--set", "smoothing.qp_options.max_iter=1"]) == 0
    err = [line for line in capsys.readouterr().err.splitlines() if "witness" in line]
    res = json.loads((out / "result.json").read_text())
    assert res["window_attempts"].get("witness", 0) > 0 and res["certificate"]["ok"] is True
    # why, in result.json and the line (a tour's raising QP backend said only this, its error text with -v alone)
    reasons = res["witness_reasons"]
    assert reasons and all("piqp: solve failed (status 'Status.PIQP_MAX_ITER_REACHED')" in r for r in reasons)
    more = f"; {len(reasons) - 1} other reasons" if len(reasons) > 1 else ""
    assert err == [f"mrfswarm: warning: {res['window_attempts']['witness']} of {res['windows']} smoothing windows had "
                   f"no solution at their planned durations and fly the rest-to-rest witness (slower, with stops) "
                   f"(last rejected: {reasons[0]}{more}): see result.json's witness_reasons; smoothing.qp_options or "
                   "the QP backend may be too tight"]


def test_a_real_process_says_the_witness_windows_once(tmp_path):
    """``plan`` issues what a run warns of as :class:`~mrfswarm.errors.PlanWarning` for Python callers; the command
    prints each line once, after its summary line, in its own words (not a second time from ``plan``)."""
    out = tmp_path / "tight"
    proc = subprocess.run([sys.executable, "-m", "mrfswarm.cli", "run", str(EXPERIMENTS / "free5.toml"), "--out",
                           str(out), "--set", "simulation.enabled=false", "--set", "smoothing.qp_options.max_iter=1"],
                          capture_output=True, text=True, timeout=300, env={**os.environ, "PYTHONPATH": str(ROOT)})
    res = json.loads((out / "result.json").read_text())
    said = [line for line in proc.stderr.splitlines() if "rest-to-rest witness" in line]
    assert proc.returncode == 0 and len(said) == 1, proc.stderr
    assert said[0].startswith(f"mrfswarm: warning: {res['windows']} of {res['windows']} smoothing windows had no "
                              "solution at their planned durations"), said
    assert "PlanWarning" not in proc.stderr, proc.stderr


def test_a_simulated_flight_closer_than_the_plan_is_said(tmp_path, capsys, monkeypatch):
    """The flown (simulated) separation below the safety distance, or a robot in an obstacle, exited 0 with only
    "flown: max tracking error" on the summary line (the arena: robots 0.183 m apart, safety 0.2 m). One warning
    line now names it; a flight within the plan says nothing."""
    import mrfswarm.pipeline

    real = mrfswarm.pipeline.Result.summary
    flown = {"min_separation_m": 0.5, "entered_obstacle": False, "max_tracking_error_m": 0.065,
             "tracking_error_bound_m": 0.18, "guaranteed_separation_m": -0.16}

    def summary(self):  # the simulation's numbers, as RotorPy would give them (its flight is not this test's)
        return {**real(self), "simulation": dict(flown)}

    monkeypatch.setattr(mrfswarm.pipeline.Result, "summary", summary)
    args = ["run", str(EXPERIMENTS / "free5.toml"), "--set", "simulation.enabled=false", "--set", "mrf.max_steps=4"]
    assert main([*args, "--out", str(tmp_path / "a")]) == 0  # 0.5 m apart, robot radius 0.25: the plan's distance
    assert "warning" not in capsys.readouterr().err
    flown["min_separation_m"] = 0.183
    assert main([*args, "--out", str(tmp_path / "b")]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["mrfswarm: warning: the simulated flight came closer than the plan: two robots 0.183 m apart, "
                   "less than twice the radius (0.5 m): their bodies touch; tracking error 6.5 cm (bound 18.0 cm, no "
                   "flown separation guaranteed): see result.json's simulation"]
    flown["min_separation_m"], flown["entered_obstacle"] = 0.6, True
    assert main([*args, "--out", str(tmp_path / "c")]) == 0
    assert "a robot inside an obstacle" in capsys.readouterr().err
    # a robot closer to a wall than its radius, its centre outside: the arena of a tour, 0.096 m at radius 0.1
    flown["entered_obstacle"], flown["min_obstacle_clearance_m"] = False, 0.2
    assert main([*args, "--out", str(tmp_path / "d")]) == 0
    assert "a robot 0.200 m from an obstacle, less than its radius (0.25 m)" in capsys.readouterr().err


def test_a_tracking_bound_past_the_radius_is_said():
    """hall20 of a tour (radius 0.1 m, bound 15 cm): result.json held guaranteed clearance -0.052 m and separation
    -0.104 m, and the run said nothing; the arena's robots (radius 0.1 m, bound 18 cm) the same."""
    from mrfswarm.cli.run import flown_warnings

    flown = {"min_separation_m": 0.9, "entered_obstacle": False, "max_tracking_error_m": 0.04,
             "tracking_error_bound_m": 0.152, "guaranteed_clearance_m": 0.1 - 0.152, "guaranteed_separation_m": -0.104}
    (text,) = flown_warnings(flown, 0.1)
    assert text.startswith("the tracking bound of this flight (15.2 cm) exceeds the robot radius (0.1 m): the "
                           "simulation guarantees no flown clearance (-0.052 m) or separation (-0.104 m)")
    assert flown_warnings({**flown, "tracking_error_bound_m": 0.08, "guaranteed_clearance_m": 0.02,
                           "guaranteed_separation_m": 0.04}, 0.1) == []
    assert flown_warnings(None, 0.1) == []
    # both: closer than the plan, and nothing guaranteed
    assert len(flown_warnings({**flown, "min_separation_m": 0.15}, 0.1)) == 2


def test_logged_warnings_read_as_the_commands_own(tmp_path):
    """Warnings came in three formats ("mrfswarm: warning: ...", "WARNING mrfswarm.maps.inline: ...", "WARNING
    solvers.qp.piqp_: ..."); a logged warning is now written as the command's own, progress keeps its module."""
    import logging
    import subprocess
    import sys

    from mrfswarm.cli import _Formatter

    def line(level: int, name: str) -> str:
        return _Formatter().format(logging.LogRecord(name, level, __file__, 1, "%d pieces", (3,), None))

    assert line(logging.WARNING, "solvers.qp.piqp_") == "mrfswarm: warning: 3 pieces"
    assert line(logging.ERROR, "mrfswarm.x") == "mrfswarm: error: 3 pieces"
    assert line(logging.INFO, "mrfswarm.continuous.receding_horizon") == "INFO mrfswarm.continuous.receding_horizon: 3 pieces"
    # the command as a user runs it: a box partly outside the map is a logged warning
    cfg = tmp_path / "box.toml"
    cfg.write_text('[scenario]\nmap = { kind = "boxes", size = [12, 8], boxes = [{ center = [20, 4], size = [2, 2] }] }\n'
                   'start = { positions = [[1, 2], [1, 5]] }\ngoal = [7, 4]\n[interaction]\nk = 1\n[mrf]\nmax_steps = 2\n'
                   '[smoothing]\nenabled = false\n[simulation]\nenabled = false\n')
    proc = subprocess.run([sys.executable, "-m", "mrfswarm.cli", "run", str(cfg), "--out", str(tmp_path / "o")],
                          capture_output=True, text=True, timeout=120)
    warned = [x for x in proc.stderr.splitlines() if "warning" in x.lower()]
    assert proc.returncode == 0 and warned and all(x.startswith("mrfswarm: warning: ") for x in warned), proc.stderr


@pytest.mark.parametrize("sets, why", [([], "smoothing.time_refinement is off"),
                                       (["--set", "smoothing.enabled=false"], "the continuous stage is off")])
def test_an_nlp_backend_the_run_does_not_use_is_one_warning_line(sets, why, tmp_path, capsys):
    out = tmp_path / "o"
    argv = ["run", str(EXPERIMENTS / "free5.toml"), "--nlp", "slsqp", "--set", "simulation.enabled=false", *sets]
    assert main([*argv, "--out", str(out)]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"mrfswarm: warning: NLP backend 'slsqp' not used: {why}"
                   + (" (--set smoothing.time_refinement=true)" if not sets else "")], err
    assert json.loads((out / "result.json").read_text())["nlp"] is None
    if not sets:  # with the refinement on, no warning, and the backend refines
        assert main([*argv, "--set", "smoothing.time_refinement=true", "--out", str(tmp_path / "r")]) == 0
        assert "not used" not in capsys.readouterr().err
        assert json.loads((tmp_path / "r" / "result.json").read_text())["nlp"] == "slsqp"


def test_the_trajectory_figure_names_the_nlp_backend_that_refined(tmp_path, capsys, monkeypatch):
    """trajectories.png's title named the QP backend alone: the runs of a comparison of NLP backends drew one title.
    It names them as the run's line does."""
    from mrfswarm import plots

    titles = []
    plot_paths = plots.plot_paths

    def spy(path, grid, paths, goal=None, title="", **kw):
        titles.append(title)
        return plot_paths(path, grid, paths, goal, title, **kw)

    monkeypatch.setattr(plots, "plot_paths", spy)
    argv = ["run", str(EXPERIMENTS / "free5.toml"), "--set", "simulation.enabled=false"]
    assert main([*argv, "--set", "smoothing.time_refinement=true", "--nlp", "slsqp", "--out", str(tmp_path / "r")]) == 0
    assert main([*argv, "--out", str(tmp_path / "d")]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert "(piqp, refined by slsqp)" in lines[0] and "(piqp)" in lines[1]
    drawn = [title for title in titles if title.startswith("smoothed trajectories")]
    assert len(drawn) == 2
    assert "(continuous seams, piqp, refined by slsqp)" in drawn[0] and "(continuous seams, piqp)" in drawn[1]


def test_a_backend_that_fails_many_attempts_without_an_iteration_cap_is_said(tmp_path, capsys):
    """SCS flew the arena 1.54 x its bound against piqp's 1.34 with no word (a solver tour): its windows' faster
    attempts ended "solved (inaccurate)" and slower ones flew. result.json counts such windows; a backend without
    an iteration cap that fails a quarter of them or more gets one line. piqp's cap fails faster attempts by
    design (clutter40: 8 of 16 windows), counted, not said."""
    free5 = ["--set", "simulation.enabled=false", "--set", "mrf.max_steps=6"]
    out = tmp_path / "osqp"
    assert main(["run", str(EXPERIMENTS / "free5.toml"), "--out", str(out), *free5, "--qp", "osqp",
                 "--set", "smoothing.qp_options.max_iter=25"]) == 0
    res = json.loads((out / "result.json").read_text())
    failures = res["solve_failures"]
    assert failures["windows"] >= res["windows"] / 4 and res["certificate"]["ok"]
    # osqp's own text, as SolverError.status holds it (result.json had its repr, "'maximum iterations reached'")
    assert failures["statuses"] == ["maximum iterations reached"]
    err = [line for line in capsys.readouterr().err.splitlines() if "did not solve" in line]
    assert err == [f"mrfswarm: warning: the QP backend osqp did not solve attempts of {failures['windows']} of "
                   f"{res['windows']} smoothing windows (status 'maximum iterations reached'): they fly slower "
                   "attempts; see result.json's solve_failures"]
    out = tmp_path / "piqp"
    assert main(["run", str(EXPERIMENTS / "free5.toml"), "--out", str(out), *free5,
                 "--set", "smoothing.qp_options.max_iter=1"]) == 0
    assert json.loads((out / "result.json").read_text())["solve_failures"]["windows"] > 0
    assert "did not solve" not in capsys.readouterr().err


def test_a_plan_cut_by_max_steps_says_which_key_to_raise(tmp_path, capsys):
    """A long way (a tour's 256 x 256 city: 0 of 30 robots at the goal after the default 300 steps) ended with
    "max_steps: robots 0, 1, ..." and no word of the key: the run says it, with the way left to go."""
    cfg = write_config(tmp_path, '[scenario]\nmap = { kind = "free", size = [30, 4] }\n'
                                 'start = { positions = [[1, 1], [1, 3]] }\ngoal = [28, 2]\n[mrf]\nmax_steps = 5\n')
    argv = ["run", str(cfg), "--set", "smoothing.enabled=false", "--set", "simulation.enabled=false"]
    assert main([*argv, "--out", str(tmp_path / "a")]) == 0
    err = capsys.readouterr().err
    assert "mrfswarm: warning: the discrete plan ended at mrf.max_steps = 5 with 2 robots on the way" in err, err
    assert "--set mrf.max_steps=100" in err
    assert "did not reach the goal" not in err  # the line above says it, with the key to raise
    assert main([*argv, "--set", "mrf.max_steps=100", "--out", str(tmp_path / "b")]) == 0
    assert "max_steps" not in capsys.readouterr().err  # all at the goal: no word


def test_a_crowd_trapped_behind_a_door_is_said_last(tmp_path, capsys):
    """20 robots behind a one-cell door under the paper's field and rules: 0 of 20 at the goal, said only inside the
    summary line's parentheses. The plan is written as any other (exit 0, as a plan cut by mrf.max_steps): the last
    line says how many did not reach the goal, and why."""
    rows = ",".join('"' + ("." * 12 + ("." if y == 10 else "#") + "." * 17) + '"' for y in range(21))
    starts = ", ".join(f"[{x}, {y}]" for x in range(2, 7) for y in range(6, 14, 2))
    cfg = write_config(tmp_path, f'[scenario]\nmap = {{ kind = "ascii", rows = [{rows}] }}\n'
                                 f'start = {{ positions = [{starts}] }}\ngoal = [24, 10]\n'
                                 '[goal_potential]\ndistance = "euclidean"\n[obstacle_potential]\ngamma = 5.0\n'
                                 '[mrf]\ncontested = "nearest"\nfollow = false\narrival = false\nmerge_waits = false\n'
                                 'drop_loops = false\nstraighten = false\nescalation = "none"\nprogress = "energy"\n'
                                 'trim_backward = false\n')
    assert main(["run", str(cfg), "--out", str(tmp_path / "out"), "--set", "smoothing.enabled=false"]) == 0
    out, err = capsys.readouterr()
    res = json.loads((tmp_path / "out" / "result.json").read_text())
    assert res["robots_at_goal"] == 0 and {r["stop_reason"] for r in res["robots"]} == {"trapped"}
    assert "robots at goal: 0/20 (trapped: robots 0, 1," in out
    assert err.splitlines()[-1] == (
        "mrfswarm: warning: 20 of 20 robots did not reach the goal: 20 trapped (the goal field leads them to a local "
        'minimum short of the goal, or they queue behind one); goal_potential.distance = "geodesic" (the default) '
        "leads around walls; the plan is written as any other (see result.json's robots)"), err
