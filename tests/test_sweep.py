"""`mrfswarm sweep` and :func:`mrfswarm.sweep.run_sweep`: the same table locally and on Dask, bad input."""

import csv
import json
import math
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from mrfswarm.cli import main
from mrfswarm.config import load_config
from mrfswarm.errors import ConfigError, ExportError
from mrfswarm.pipeline import plan
from mrfswarm.sweep import SchedulerError, is_timing_column, parse_grid, run_sweep, toml_literal
from support.added_backends import registered
from support.repository import EXPERIMENTS

FREE5 = EXPERIMENTS / "free5.toml"
FAST = ["smoothing.enabled=false", "mrf.max_steps=8"]
GRID = {"interaction.k_a": [10, 14], "interaction.k_r": [2.0, 4.0]}
GOAL_GRID = {"scenario.goal": [[30, 20], [12, 12]], "interaction.k": [2, 3]}  # (12, 12) is inside a block

BLOCKS5 = """[scenario]
map = { kind = "boxes", size = [40, 40], boxes = [{ center = [12.5, 12.5], size = [5, 5] }] }
start = { positions = [[2, 7], [4, 5], [4, 9], [6, 7], [4, 7]] }
goal = [30, 20]
"""


def values(rows):
    """The rows without the measured times (those differ between runs)."""
    return [{k: v for k, v in r.items() if not is_timing_column(k)} for r in rows]


def read_csv(path):
    with open(path, newline="") as f:
        return list(csv.reader(f))


@pytest.fixture(scope="module")
def cluster():
    distributed = pytest.importorskip("distributed")
    c = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                 dashboard_address=None)
    yield c
    c.close()


@pytest.fixture(scope="module")
def local(tmp_path_factory):
    """The reference sweep: 2 x 2 points in local processes."""
    return run_sweep(FREE5, GRID, tmp_path_factory.mktemp("local"), workers=2, overrides=FAST)


SWARM14 = """[scenario]
map = { kind = "free", size = [24, 16] }
start = { positions = [%s] }
goal = [10, 8]

[simulation]
backend = "processes"
""" % ", ".join(f"[{x}, {y}]" for x in (2, 4) for y in range(2, 16, 2))


def test_a_dask_worker_plans_and_flies_without_a_pool_of_its_own(cluster, tmp_path):
    """A Dask worker runs in a daemonic process, which may not start processes: 14 robots (the window QPs solved
    in a pool from 13) flown one robot per process failed with "daemonic processes are not allowed to have
    children", and the sweep wrote no table. The worker now solves and flies them in its own process."""
    config = tmp_path / "swarm14.toml"
    config.write_text(SWARM14)
    r = run_sweep(config, {"interaction.k": [3, 4]}, tmp_path / "dask", scheduler=cluster.scheduler_address)
    assert [row["error"] for row in r.rows] == [None, None]
    assert all(row["n_robots"] == 14 and row["simulation_max_tracking_error_m"] > 0 for row in r.rows)


def test_a_registered_method_reaches_the_dask_workers(cluster, tmp_path):
    """The sweep's points carry the backends its process registered: a Dask worker never ran the script."""
    with registered():
        r = run_sweep(FREE5, {"mrf.method": ["icm", "icm_twin"]}, tmp_path / "dask", scheduler=cluster.scheduler_address,
                      overrides=FAST)
    assert [row["error"] for row in r.rows] == [None, None]  # "unknown MRF method 'icm_twin'" on the worker before
    assert r.rows[0]["mrf_steps"] == r.rows[1]["mrf_steps"]


def test_same_table_in_process_and_on_dask(local, cluster, tmp_path):
    ref = values(local.rows)
    assert [(r["point"], r["interaction.k_a"], r["interaction.k_r"]) for r in ref] == [
        (0, 10, 2.0), (1, 10, 4.0), (2, 14, 2.0), (3, 14, 4.0)]  # row-major in the order given
    assert all(r["error"] is None and r["n_robots"] == 5 for r in ref)
    assert len({r["mean_inter_robot_distance_final"] for r in ref}) == 4  # the grid changes the result
    one = run_sweep(FREE5, GRID, tmp_path / "one", workers=1, overrides=FAST)
    on_dask = run_sweep(FREE5, GRID, tmp_path / "dask", scheduler=cluster.scheduler_address, overrides=FAST)
    assert values(one.rows) == ref
    assert values(on_dask.rows) == ref
    assert on_dask.columns == local.columns == one.columns
    # the CSVs agree cell by cell, timing columns aside
    keep = [i for i, c in enumerate(local.columns) if not is_timing_column(c)]
    tables = [[[row[i] for i in keep] for row in read_csv(r.csv_path)] for r in (local, one, on_dask)]
    assert tables[0] == tables[1] == tables[2]


def test_row_is_plan_of_the_overridden_config(local):
    """Point 1 is load_config(config, overrides + [k_a=10, k_r=4.0]) planned, nothing else."""
    s = plan(load_config(FREE5, FAST + ["interaction.k_a=10", "interaction.k_r=4.0"])).summary()
    row = local.rows[1]
    for k in ("mrf_steps", "converged", "stop_reason", "min_separation_discrete", "mean_inter_robot_distance_final"):
        assert row[k] == s[k], k
    cfg = json.loads((next((local.out_dir / "points").glob("001_*")) / "result.json").read_text())["config"]
    assert cfg["interaction"]["k_a"] == 10.0 and cfg["interaction"]["k_r"] == 4.0 and cfg["mrf"]["max_steps"] == 8


def test_result_json_and_csv_match_rows(local):
    dirs = sorted((local.out_dir / "points").iterdir())
    assert [d.name for d in dirs] == ["000_k_a=10_k_r=2.0", "001_k_a=10_k_r=4.0", "002_k_a=14_k_r=2.0",
                                      "003_k_a=14_k_r=4.0"]
    for d, row in zip(dirs, local.rows):
        res = json.loads((d / "result.json").read_text())
        assert res["config"]["interaction"]["k_a"] == row["interaction.k_a"]
        for k, v in row.items():
            if k in ("point", "interaction.k_a", "interaction.k_r", "wall_s", "error"):
                continue
            if k.startswith("mrf_step_time_"):
                assert res["mrf_step_time_s"][k[len("mrf_step_time_"):-2]] == v, k
            elif k.startswith("time_"):
                assert res["timings_s"][k[len("time_"):-2]] == v, k
            elif k == "swarm_energy_final":
                assert res["swarm_energy"][-1] == v
            else:
                assert res[k] == v, k
        assert "error" not in res
        assert {"graph", "cliques", "labels", "energy", "optimizer"} <= set(res["mrf_step_time_s"])
    table = read_csv(local.csv_path)
    assert table[0] == local.columns and len(table) == 1 + 4
    assert table[0][:3] == ["point", "interaction.k_a", "interaction.k_r"] and table[0][-2:] == ["wall_s", "error"]
    assert {"n_robots", "mrf_steps", "converged", "stop_reason", "reached_goal", "min_separation_discrete",
            "min_separation_continuous", "mean_inter_robot_distance_final", "makespan_s",
            "mrf_step_time_optimizer_s"} <= set(table[0])
    col = table[0].index("mean_inter_robot_distance_final")
    assert [float(r[col]) for r in table[1:]] == [r["mean_inter_robot_distance_final"] for r in local.rows]
    meta = json.loads(local.json_path.read_text())
    assert meta["complete"] is True and meta["grid"] == {"interaction.k_a": [10, 14], "interaction.k_r": [2.0, 4.0]}
    assert meta["config"] == str(FREE5) and values(meta["rows"]) == values(local.rows)


def test_seeds_one_row_per_point_and_seed(tmp_path):
    res = run_sweep(FREE5, {"interaction.k": [2, 3]}, tmp_path, workers=1, seeds=[0, 5], overrides=FAST)
    assert [(r["point"], r["interaction.k"], r["seed"]) for r in res.rows] == [(0, 2, 0), (0, 2, 5), (1, 3, 0),
                                                                              (1, 3, 5)]
    names = sorted(d.name for d in (tmp_path / "points").iterdir())
    assert names == ["000_k=2_seed=0", "000_k=2_seed=5", "001_k=3_seed=0", "001_k=3_seed=5"]
    s = plan(load_config(FREE5, FAST + ["interaction.k=3"]), seed=5).summary()
    assert res.rows[3]["mean_inter_robot_distance_final"] == s["mean_inter_robot_distance_final"]
    assert res.rows[2]["mean_inter_robot_distance_final"] != res.rows[3]["mean_inter_robot_distance_final"]
    assert read_csv(res.csv_path)[0][:3] == ["point", "interaction.k", "seed"]


@pytest.mark.parametrize("where", ["in process", "dask"])
def test_failing_points_are_rows(where, tmp_path, request):
    cfg = tmp_path / "blocks5.toml"
    cfg.write_text(BLOCKS5)
    grid = {"scenario.goal": [[30, 20], [12, 12]], "interaction.k": [2, 5]}  # goal in the block; k >= N = 5
    kw = {"workers": 1} if where == "in process" else {"scheduler": request.getfixturevalue("cluster")}
    res = run_sweep(cfg, grid, tmp_path / "out", overrides=FAST, **kw)
    errors = [r["error"] for r in res.rows]
    assert errors[0] is None and res.rows[0]["n_robots"] == 5 and res.rows[0]["mrf_steps"] >= 1
    assert "interaction.k = 5" in errors[1] and "inside an obstacle" in errors[2] and errors[3] is not None
    assert len(res.failed) == 3 and all("\n" not in e for e in errors[1:])
    for d, row in zip(sorted((tmp_path / "out" / "points").iterdir()), res.rows):
        assert json.loads((d / "result.json").read_text()).get("error") == row["error"]
    table = read_csv(res.csv_path)
    assert len(table) == 5 and table[1][table[0].index("error")] == ""
    assert table[2][table[0].index("mrf_steps")] == ""  # a failed point has no results


def test_bug_in_a_point_propagates_and_finished_points_are_kept(tmp_path, monkeypatch):
    import mrfswarm.pipeline

    real = mrfswarm.pipeline.plan
    calls = []

    def flaky(cfg, **kw):
        calls.append(cfg)
        if len(calls) == 3:
            raise RuntimeError("a bug")
        return real(cfg, **kw)

    monkeypatch.setattr(mrfswarm.pipeline, "plan", flaky)
    with pytest.raises(RuntimeError, match="a bug"):
        run_sweep(FREE5, GRID, tmp_path, workers=1, overrides=FAST)
    table = read_csv(tmp_path / "sweep.csv")
    assert [r[0] for r in table[1:]] == ["0", "1"]
    meta = json.loads((tmp_path / "sweep.json").read_text())
    assert meta["complete"] is False and meta["finished"] == 2 and meta["runs"] == 4
    assert len(list((tmp_path / "points").glob("*/result.json"))) == 2


def test_cli_sweep(tmp_path, capsys):
    out = tmp_path / "out"
    rc = main(["sweep", str(FREE5), "--grid", "interaction.k=2,3", "--out", str(out), "--workers", "1",
               "--seeds", "1,2", "--set", "smoothing.enabled=false", "--set", "mrf.max_steps=4"])
    assert rc == 0
    assert "4 runs (0 failed)" in capsys.readouterr().out
    table = read_csv(out / "sweep.csv")
    assert table[0][:3] == ["point", "interaction.k", "seed"] and len(table) == 5
    assert all(int(r[table[0].index("mrf_steps")]) <= 4 for r in table[1:])


def test_a_folder_holding_a_sweep_is_refused_or_replaced_with_overwrite(tmp_path, capsys, monkeypatch):
    """A second sweep into a sweep's folder mixed its points with the first's (four old points beside one new);
    a folder that is not a sweep's was written into as well."""
    out = tmp_path / "out"
    args = ["sweep", str(FREE5), "--out", str(out), "--workers", "1", "--set", "smoothing.enabled=false",
            "--set", "mrf.max_steps=4"]
    assert main([*args, "--grid", "interaction.k=2,3"]) == 0
    first = sorted(p.name for p in (out / "points").iterdir())
    assert len(first) == 2
    capsys.readouterr()
    assert main([*args, "--grid", "interaction.k=2"]) == 2  # refused before planning
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "already holds a sweep" in err and "--overwrite" in err
    assert "in Python" not in err and "overwrite=True" not in err, err  # the command's way only
    with pytest.raises(ExportError, match=r"already holds a sweep .*\(in Python: overwrite=True\)"):
        run_sweep(FREE5, {"interaction.k": [2]}, out, workers=1)
    assert sorted(p.name for p in (out / "points").iterdir()) == first
    assert main([*args, "--grid", "interaction.k=4", "--overwrite"]) == 0
    assert [p.name for p in (out / "points").iterdir()] == ["000_k=4"]
    assert len(read_csv(out / "sweep.csv")) == 2 and not [p for p in tmp_path.iterdir() if p.name.startswith(".")]
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("keep me")
    capsys.readouterr()
    assert main([*args[:2], "--out", str(mine), *args[4:], "--grid", "interaction.k=2", "--overwrite"]) == 2
    assert "not an mrfswarm sweep's" in capsys.readouterr().err and [p.name for p in mine.iterdir()] == ["notes.txt"]
    # a replacing sweep that fails keeps the one it replaces, beside
    import mrfswarm.pipeline

    def broken(cfg, **kw):
        raise RuntimeError("a bug")

    monkeypatch.setattr(mrfswarm.pipeline, "plan", broken)
    with pytest.raises(RuntimeError, match="a bug"):
        run_sweep(FREE5, {"interaction.k": [2]}, out, workers=1, overwrite=True)
    kept = [p for p in tmp_path.iterdir() if p.name.startswith(".out.old-")]
    assert len(kept) == 1 and [p.name for p in (kept[0] / "out" / "points").iterdir()] == ["000_k=4"]


BAD = {
    "no equals sign": (["--grid", "interaction.k_a"], "expected KEY=V1,V2"),
    "empty value list": (["--grid", "interaction.k_a="], "empty value list"),
    "empty value": (["--grid", "interaction.k_a=8,,14"], "empty value"),
    "unknown key": (["--grid", "interaction.k_x=1,2"], "unknown config key interaction.k_x"),
    "unknown section": (["--grid", "interactions.k=1,2"], "unknown config section"),
    "wrong type": (["--grid", "interaction.k=two"], "interaction.k must be an integer"),
    "wrong type at the last point": (["--grid", "interaction.k=2,3,3.5"], "sweep point 2 (interaction.k=3.5)"),
    "out of range": (["--grid", "mrf.order=2,0"], "mrf.order = 0: must be in 1..32"),
    "Morse conditions": (["--grid", "interaction.k_a=14,3"],
                         "sweep point 1 (interaction.k_a=3): interaction.k_a = 3.0: must be > interaction.k_r = 4.0"),
    "unknown method": (["--grid", "mrf.method=icm,nosuch"], "nosuch"),
    "bad seeds": (["--grid", "interaction.k=2", "--seeds", "0,x"], "--seeds"),
    # two runs of one point and seed shared a folder: the second's result.json replaced the first's
    "a seed twice": (["--grid", "interaction.k=2", "--seeds", "0,1,0"], "--seeds: 0 is given twice"),
    "empty scheduler address": (["--grid", "interaction.k=2", "--scheduler", " "], "--scheduler: empty address"),
    "zero workers": (["--grid", "interaction.k=2", "--workers", "0"], "--workers 0"),
    "no grid": ([], "--grid"),
    "unreachable scheduler": (["--grid", "interaction.k=2,3", "--scheduler", "tcp://127.0.0.1:9",
                               "--connect-timeout", "1"], "cannot reach the Dask scheduler at 'tcp://127.0.0.1:9'"),
}


@pytest.mark.parametrize("name", list(BAD))
def test_bad_input_one_line_exit_2_nothing_written(name, tmp_path, capsys):
    args, match = BAD[name]
    if "--scheduler" in args:
        pytest.importorskip("distributed")
    out = tmp_path / "out"
    try:
        rc = main(["sweep", str(FREE5), "--out", str(out), "--set", "smoothing.enabled=false", *args])
    except SystemExit as e:  # argparse's own errors (a missing option, a non-integer --workers)
        rc = e.code
    err = capsys.readouterr().err
    assert rc == 2
    assert err.startswith("mrfswarm: error:") and err.count("\n") == 1, err
    assert match in err, err
    assert not out.exists()


def test_dask_not_installed(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)  # `import distributed` now fails as if absent
    out = tmp_path / "out"
    rc = main(["sweep", str(FREE5), "--grid", "interaction.k=2", "--out", str(out), "--scheduler", "tcp://x:1"])
    err = capsys.readouterr().err
    assert rc == 2 and 'pip install "mrfswarm[dask]"' in err and err.count("\n") == 1
    assert not out.exists()
    with pytest.raises(SchedulerError):
        run_sweep(FREE5, {"interaction.k": [2]}, out, scheduler="tcp://x:1")


def test_parse_grid_literals():
    g = parse_grid(["interaction.k=3,7", "interaction.k_a=8,14.5,1e1", "mrf.method=icm,\"gibbs\"",
                    "mrf.trim_backward=true,false", "scenario.goal=[35,15], [30, 20.5]",
                    "scenario.start={center=[1,2], n_robots=3},{positions=[[1,1],[2,2]]}", "x.s='a,b',c"])
    assert g == {
        "interaction.k": [3, 7],
        "interaction.k_a": [8, 14.5, 10.0],
        "mrf.method": ["icm", "gibbs"],
        "mrf.trim_backward": [True, False],
        "scenario.goal": [[35, 15], [30, 20.5]],
        "scenario.start": [{"center": [1, 2], "n_robots": 3}, {"positions": [[1, 1], [2, 2]]}],
        "x.s": ["a,b", "c"],
    }
    assert [type(v) for v in g["interaction.k_a"]] == [int, float, float]
    assert list(g) == ["interaction.k", "interaction.k_a", "mrf.method", "mrf.trim_backward", "scenario.goal",
                       "scenario.start", "x.s"]


@pytest.mark.parametrize("item, match", [("k", "expected KEY="), ("=1", "empty key"), ("a..b=1", "empty key"),
                                         ("a.b=", "empty value list"), ("a.b=1,", "empty value")])
def test_parse_grid_errors(item, match):
    with pytest.raises(ConfigError, match=match):
        parse_grid([item])
    with pytest.raises(ConfigError, match="given twice"):
        parse_grid(["a.b=1", "a.b=2"])


toml_values = st.recursive(
    st.booleans() | st.integers(-2**63, 2**63 - 1) | st.floats(allow_nan=False)
    | st.text(st.characters(blacklist_categories=("Cs",)), max_size=8),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=4), inner, max_size=3),
    max_leaves=8)


@given(toml_values)
def test_toml_literal_round_trips_through_parse_grid(v):
    """A Python grid value becomes the --set item that reads back exactly that value."""
    got = parse_grid([f"a.b={toml_literal(v)}"])["a.b"]
    assert got == [v] and type(got[0]) is type(v)
    if isinstance(v, float):
        assert math.copysign(1, got[0]) == math.copysign(1, v)


def test_grid_values_from_python(tmp_path):
    """The Python API takes the grid as values (here floats and a list), written as TOML for load_config."""
    cfg = tmp_path / "b.toml"
    cfg.write_text(BLOCKS5)
    res = run_sweep(cfg, {"scenario.goal": [(30.0, 20.0)], "interaction.a": [0.7]}, tmp_path / "o", workers=1,
                    overrides=FAST)
    assert res.rows[0]["error"] is None and res.rows[0]["scenario.goal"] == (30.0, 20.0)
    assert read_csv(res.csv_path)[1][1] == "[30.0, 20.0]"
    with pytest.raises(ConfigError, match="cannot be written in TOML"):
        run_sweep(cfg, {"scenario.goal": [None]}, tmp_path / "p")
    assert not (tmp_path / "p").exists()


def test_points_on_threads_of_one_process_agree():
    """A Dask worker with several threads plans points at once: same results as one by one."""
    import concurrent.futures as cf

    from mrfswarm import sweep

    cfg = load_config(FREE5, ["simulation.enabled=false", "mrf.max_steps=6"])
    task = sweep._Task(cfg, None, "unused", False)
    serial = sweep._run_point(task)
    with cf.ThreadPoolExecutor(4) as ex:
        outs = list(ex.map(lambda _: sweep._run_point(task), range(4)))
    for out in outs:
        assert out["error"] is None
        a, b = dict(out["summary"]), dict(serial["summary"])
        for d in (a, b):
            d.pop("timings_s"), d.pop("mrf_step_time_s")
        assert a == b


def test_a_smoothed_sweep_tabulates_the_flight_against_its_lower_bound(tmp_path):
    """With smoothing, each row holds the run's flight_quality scalars (makespan over its lower bound, stops),
    as its result.json has them."""
    res = run_sweep(EXPERIMENTS / "corridor.toml", {"smoothing.time_weight": [10, 20]}, tmp_path, workers=1,
                    overrides=["simulation.enabled=false"])
    for d, row in zip(sorted((tmp_path / "points").iterdir()), res.rows):
        q = json.loads((d / "result.json").read_text())["flight_quality"]
        for k in ("lower_bound_s", "makespan_over_bound", "bound_robot", "stops_per_robot", "stops_max",
                  "mean_speed_m_s"):
            assert row[k] == q[k], k
        assert row["makespan_over_bound"] > 1 and "stops" not in row  # the per-robot list stays in result.json
    header = read_csv(res.csv_path)[0]
    assert {"makespan_over_bound", "stops_per_robot", "lower_bound_s"} <= set(header)


def test_a_sweep_tabulates_the_certificate_the_sampled_check_and_the_limits_reached(tmp_path):
    """The tables of result.json (certificate, sampled check, limits asked and reached) are columns <table>_<key>;
    the sampled check's are empty where the check is off (its table was a column left empty in every row)."""
    res = run_sweep(EXPERIMENTS / "corridor.toml", {"smoothing.check_rate_hz": [0, 500]}, tmp_path, workers=1,
                    overrides=["simulation.enabled=false"])
    header = read_csv(res.csv_path)[0]
    assert "sampled_check" not in header and "certificate" not in header
    off, on = res.rows
    points = sorted((tmp_path / "points").iterdir())
    summary = [json.loads((d / "result.json").read_text()) for d in points]
    assert summary[0]["sampled_check"] is None and off.get("sampled_check_min_separation_m") is None
    assert on["sampled_check_rate_hz"] == 500
    assert on["sampled_check_min_separation_m"] == summary[1]["sampled_check"]["min_separation_m"] > 0
    for row, s in zip(res.rows, summary):
        assert row["certificate_ok"] is True and row["certificate_ok"] == s["certificate"]["ok"]
        assert row["achieved_j_max"] == s["achieved"]["j_max"] <= row["limits_j_max"] == s["limits"]["j_max"]
        assert row["piece_limit_fits"] == s["piece_limit"]["fits"]
    table = read_csv(res.csv_path)
    column = table[0].index("sampled_check_min_separation_m")
    assert table[1][column] == "" and float(table[2][column]) == on["sampled_check_min_separation_m"]


def test_point_folders_name_list_values_readably():
    """A list value gave ``goal=-4-3`` (read as negative numbers); its items are joined by ``x``."""
    from mrfswarm.sweep import _slug

    assert _slug({"scenario.goal": [4, 3]}, None) == "goal=4x3"
    assert _slug({"scenario.goal": [-4, 3.5], "interaction.k_a": 8}, 2) == "goal=-4x3.5_k_a=8_seed=2"


def test_a_discrete_only_point_leaves_no_empty_table_column_and_the_solve_failures_are_counted(tmp_path):
    """A point without smoothing has ``flight_quality`` null: it was a column of its own, empty in every row, beside
    the flight_quality scalars of the smoothed points; ``solve_failures`` (the windows the QP backend failed to
    solve, what a sweep over backends compares) was no column at all."""
    res = run_sweep(EXPERIMENTS / "corridor.toml", {"smoothing.enabled": [False, True]}, tmp_path, workers=1,
                    overrides=["simulation.enabled=false"])
    header = read_csv(res.csv_path)[0]
    assert "flight_quality" not in header and "solve_failures" not in header
    assert {"makespan_over_bound", "solve_failures_windows"} <= set(header)
    discrete, smoothed = res.rows
    summary = json.loads((sorted((tmp_path / "points").iterdir())[1] / "result.json").read_text())
    assert discrete.get("makespan_over_bound") is None and discrete.get("solve_failures_windows") is None
    assert smoothed["solve_failures_windows"] == summary["solve_failures"]["windows"]


def test_a_sweep_over_mrf_methods_tabulates_the_final_swarm_energy(tmp_path):
    """What the methods minimize, the swarm energy of the final configuration (the ablation's "final energy"), was
    no column: result.json holds it only as the per-step list ``swarm_energy``."""
    res = run_sweep(FREE5, {"mrf.method": ["icm", "trws"]}, tmp_path, workers=1, overrides=FAST)
    assert "swarm_energy" not in res.columns and "swarm_energy_final" in read_csv(res.csv_path)[0]
    for d, row in zip(sorted((tmp_path / "points").iterdir()), res.rows):
        assert row["swarm_energy_final"] == json.loads((d / "result.json").read_text())["swarm_energy"][-1]
    icm, trws = res.rows
    assert trws["swarm_energy_final"] < icm["swarm_energy_final"]  # paper_figs/ablation.md: free5, -1.43 %


def test_figures_leave_each_point_folder_as_a_run_writes_one(tmp_path):
    """With figures, a point's folder is written as `mrfswarm run` writes one, result.json with ``"complete": true``
    last; the sweep then wrote its own result.json over it, without that flag."""
    res = run_sweep(FREE5, {"interaction.k": [2, 3]}, tmp_path, workers=1, overrides=FAST, figures=True)
    for d, row in zip(sorted((tmp_path / "points").iterdir()), res.rows):
        assert (d / "discrete_paths.csv").is_file() and any((d / "figures").glob("*.png"))
        data = json.loads((d / "result.json").read_text())
        assert data["complete"] is True and data["mrf_steps"] == row["mrf_steps"] and "error" not in data


def test_an_interrupted_sweep_says_where_its_finished_rows_are(tmp_path, monkeypatch, caplog):
    """Ctrl-C mid-sweep printed "mrfswarm: interrupted" alone, though the finished points' rows were tabulated."""
    import mrfswarm.pipeline

    real = mrfswarm.pipeline.plan
    calls = []

    def interrupted(cfg, **kw):
        calls.append(cfg)
        if len(calls) == 3:
            raise KeyboardInterrupt
        return real(cfg, **kw)

    monkeypatch.setattr(mrfswarm.pipeline, "plan", interrupted)
    with pytest.raises(KeyboardInterrupt):
        run_sweep(FREE5, GRID, tmp_path / "out", workers=1, overrides=FAST)
    meta = json.loads((tmp_path / "out" / "sweep.json").read_text())
    assert meta["complete"] is False and meta["finished"] == 2 and meta["runs"] == 4
    said = [r.getMessage() for r in caplog.records if r.levelname == "WARNING"]
    assert any("2 of 4 runs" in m and str(tmp_path / "out" / "sweep.csv") in m for m in said), said


def test_a_setting_the_points_leave_unused_is_said_once_in_one_line(tmp_path, capfd):
    """A worker process printed the warning in Python's own format (file, line, source line), once per worker;
    in the sweep's process each point said again what building the points had said."""
    rc = main(["sweep", str(FREE5), "--grid", "interaction.k=2,3", "--out", str(tmp_path / "a"), "--workers", "2",
               "--set", "scenario.downwash=2", *(f"--set={s}" for s in FAST)])
    err = capfd.readouterr().err.splitlines()
    assert rc == 0 and err == ["mrfswarm: warning: scenario.downwash = 2 not used: on a 2-D map every robot flies at "
                               "one altitude"], err
    rc = main(["sweep", str(EXPERIMENTS / "corridor.toml"), "--grid", "smoothing.nlp=slsqp,lbfgsb", "--out",
               str(tmp_path / "b"), "--workers", "1", "--set", "simulation.enabled=false", "--set", "mrf.max_steps=3"])
    err = capfd.readouterr().err.splitlines()
    assert rc == 0 and len(err) == 2 and all(line.startswith("mrfswarm: warning: smoothing.nlp = ") for line in err), err


@pytest.mark.parametrize("workers", [2, 1])
def test_a_maps_warning_names_the_point_it_came_from_once(workers, tmp_path, capfd, caplog):
    """A box reaching past its cells is said once per sweep, naming the point (it was said bare by every point)."""
    cfg = tmp_path / "blocks5.toml"
    cfg.write_text(BLOCKS5)
    rc = main(["sweep", str(cfg), "--grid", "interaction.k=2,3", "--out", str(tmp_path / "out"),
               "--workers", str(workers), "--set", "smoothing.enabled=false", "--set", "mrf.max_steps=3"])
    text = "scenario.map.boxes[0] (center [12.5, 12.5], size [5, 5]) reaches 0.5 m past the cells it fills"
    bare = [line for line in capfd.readouterr().err.splitlines() if text in line]
    said = [r.getMessage() for r in caplog.records if r.levelname == "WARNING" and text in r.getMessage()]
    assert rc == 0 and not bare and len(said) == 2, (bare, said)
    assert said[0].startswith(("sweep point 0 (interaction.k=2): ", "sweep point 1 (interaction.k=3): ")), said
    assert said[1].endswith(("also in sweep point 1 (interaction.k=3)", "also in sweep point 0 (interaction.k=2)"))


@pytest.mark.parametrize("workers", [2, 1])
def test_a_backends_warning_names_the_point_it_came_from_once(workers, tmp_path, capfd, caplog):
    """A spawned worker printed the QP backend's warning bare, once per worker process (a tour's osqp sweep: two
    unprefixed "reduced accuracy" lines for 3 points), and in one process once per sweep, no point named."""
    rc = main(["sweep", str(EXPERIMENTS / "corridor.toml"), "--grid", "smoothing.v_max=2.0,1.5", "--out",
               str(tmp_path / "out"), "--workers", str(workers), "--set", "simulation.enabled=false",
               "--set", "mrf.max_steps=3", "--set", "smoothing.qp_options.time_limit=30"])
    text = "piqp has no time limit; Options.time_limit=30.0 is ignored"
    bare = [line for line in capfd.readouterr().err.splitlines() if text in line]
    said = [r.getMessage() for r in caplog.records if r.levelname == "WARNING" and text in r.getMessage()]
    names = ["sweep point 0 (smoothing.v_max=2.0)", "sweep point 1 (smoothing.v_max=1.5)"]
    first = next((n for n in names if said and said[0] == f"{n}: {text}"), None)
    assert rc == 0 and not bare and first is not None and len(said) == 2, (bare, said)
    other = next(n for n in names if n != first).removeprefix("sweep ")
    assert said[1] == f"{text}: also in sweep {other}", said
    if workers == 1:  # in point order
        assert first == names[0], said


@pytest.mark.parametrize("workers", [2, 1])
def test_what_a_points_plan_warns_of_is_said_once_naming_the_point(workers, tmp_path, capfd, caplog):
    """``plan`` issues what a run warns of (windows flown as their rest-to-rest witness) as a PlanWarning; a sweep's
    worker printed it in Python's format once per point. It is said once per sweep, naming the point, as a
    backend's warning is."""
    rc = main(["sweep", str(FREE5), "--grid", "simulation.rate_hz=100,200", "--out", str(tmp_path / "out"),
               "--workers", str(workers), "--set", "simulation.enabled=false",
               "--set", "smoothing.qp_options.max_iter=1"])
    text = "smoothing windows had no solution at their planned durations and fly the rest-to-rest witness"
    bare = [line for line in capfd.readouterr().err.splitlines() if text in line]
    said = [r.getMessage() for r in caplog.records if r.levelname == "WARNING" and text in r.getMessage()]
    names = ["sweep point 0 (simulation.rate_hz=100)", "sweep point 1 (simulation.rate_hz=200)"]
    first = next((n for n in names if said and said[0].startswith(f"{n}: ")), None)
    assert rc == 0 and not bare and first is not None and len(said) == 2, (bare, said)
    other = next(n for n in names if n != first).removeprefix("sweep ")
    assert said[1] == f"{said[0].removeprefix(first + ': ')}: also in sweep {other}", said


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM], ids=["ctrl-c", "sigterm"])
def test_a_stopped_sweep_leaves_no_half_written_point_folder(tmp_path, signum):
    """With figures, a worker writes its point's folder as `mrfswarm run` does, into a hidden ``.NAME.partial-*``
    folder renamed into place at the end; Ctrl-C or SIGTERM stops the workers outright, and that folder stayed in
    ``points/`` (a tour's ``.001_method=gibbs.partial-weywbyc8``)."""
    out = tmp_path / "out"
    slow = tmp_path / "slow.py"  # the real CLI, a point's outputs slow to write, so the signal lands meanwhile
    slow.write_text("import sys, time\nimport mrfswarm.outputs as o\nreal = o.write_discrete_outputs\n"
                    "def write(*a, **k):\n    sys.stdout.write('writing\\n'); sys.stdout.flush()\n    time.sleep(30)\n"
                    "    return real(*a, **k)\no.write_discrete_outputs = write\n"  # the spawned workers import it too
                    "if __name__ == '__main__':\n    from mrfswarm.cli import main\n    sys.exit(main(sys.argv[1:]))\n")
    root = Path(__file__).resolve().parents[1]
    proc = subprocess.Popen([sys.executable, str(slow), "sweep", str(FREE5), "--grid", "mrf.method=icm,trws",
                             "--figures", "--workers", "2", "--out", str(out), *(f"--set={s}" for s in FAST)],
                            cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            env={**os.environ, "PYTHONPATH": str(root)}, start_new_session=True,
                            # Ctrl-C as from a terminal: a process started with SIGINT ignored keeps it ignored (Python
                            # installs no KeyboardInterrupt handler), and a test before this one in the same pytest
                            # worker can leave it so: the sweep then ran to its end (exit 0) in the full suite
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        assert proc.stdout.readline() == b"writing\n"
        assert [p.name for p in (out / "points").iterdir() if ".partial-" in p.name]  # the folder being written
        os.killpg(proc.pid, signum) if signum == signal.SIGINT else proc.send_signal(signum)  # Ctrl-C: the group
        proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == (130 if signum == signal.SIGINT else 143)
    assert not list(out.iterdir())  # no point had finished: nothing left in the way of the next sweep
    main(["sweep", str(FREE5), "--grid", "mrf.method=icm", "--workers", "1", "--out", str(out),
          *(f"--set={s}" for s in FAST)])
    assert (out / "sweep.json").is_file()
