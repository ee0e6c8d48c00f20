"""The config: one name per solver choice (``mrf.method``, ``smoothing.backend``), old names that still load."""

import contextlib
import dataclasses
import json
import warnings
from pathlib import Path

import numpy as np
import pytest

import solvers.qp
from mrfswarm.cli import main
from mrfswarm.config import apply_overrides, from_dict, load_config
from mrfswarm.continuous import receding_horizon
from mrfswarm.continuous.receding_horizon import QP_OPTIONS
from mrfswarm.errors import ConfigError, DeprecatedKeyWarning, ScenarioError, UnusedSettingWarning
from mrfswarm.pipeline import mrf_options, plan, qp_options, resolve_config
from mrfswarm.scenario import build_scenario
from mrfswarm.sweep import run_sweep
from solvers import mrf
from support.repository import EXPERIMENTS

QUICK = ["smoothing.enabled=false", "mrf.max_steps=3"]


def write(tmp_path: Path, body: str) -> Path:
    p = tmp_path / "c.toml"
    p.write_text(body)
    return p


def test_the_old_key_loads_as_method_with_one_warning(tmp_path):
    with pytest.warns(DeprecatedKeyWarning, match=r"mrf\.optimizer is now mrf\.method") as caught:
        cfg = load_config(write(tmp_path, '[mrf]\noptimizer = "gibbs"\n'))
    assert cfg.mrf.method == "gibbs" and len(caught) == 1
    assert cfg.to_dict()["mrf"]["method"] == "gibbs" and "optimizer" not in cfg.to_dict()["mrf"]


def test_the_new_key_loads_without_a_warning(tmp_path):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert load_config(write(tmp_path, '[mrf]\nmethod = "exact"\n')).mrf.method == "exact"


def test_both_names_are_an_error_naming_both(tmp_path):
    with pytest.raises(ConfigError, match=r"^mrf\.optimizer and mrf\.method are both given.*keep mrf\.method$"):
        load_config(write(tmp_path, '[mrf]\noptimizer = "icm"\nmethod = "gibbs"\n'))
    with pytest.raises(ConfigError, match="both given"):
        from_dict({"mrf": {"method": "icm", "optimizer": "icm"}})


@pytest.mark.parametrize("overrides", [["mrf.optimizer=icm", "mrf.method=gibbs"],
                                       ["mrf.method=gibbs", "mrf.optimizer=icm"]])
def test_both_names_in_the_overrides_are_an_error_as_in_a_file(overrides):
    with pytest.warns(DeprecatedKeyWarning), pytest.raises(
            ConfigError, match=r"^mrf\.optimizer and mrf\.method are both given.*keep mrf\.method$"):
        apply_overrides({}, overrides)


def test_one_name_given_twice_in_the_overrides_is_the_last_one():
    assert apply_overrides({}, ["mrf.method=icm", "mrf.method=gibbs"])["mrf"]["method"] == "gibbs"


def test_a_wrong_type_under_the_old_name_names_the_new_key():
    with pytest.warns(DeprecatedKeyWarning), pytest.raises(ConfigError, match=r"mrf\.method must be a string, got 3"):
        from_dict({"mrf": {"optimizer": 3}})


@pytest.mark.parametrize("body, override, method, warned", [
    ("", "mrf.optimizer=gibbs", "gibbs", 1),  # the old name overrides the default
    ('[mrf]\nmethod = "icm"\n', "mrf.optimizer=gibbs", "gibbs", 1),  # ... and the new name in the file
    ('[mrf]\noptimizer = "icm"\n', "mrf.method=exact", "exact", 1),  # the new name overrides the old one
    ('[mrf]\noptimizer = "icm"\n', "mrf.optimizer=exact", "exact", 2),
])
def test_overrides_set_the_current_name(tmp_path, body, override, method, warned):
    with pytest.warns(DeprecatedKeyWarning) as caught:
        cfg = load_config(write(tmp_path, body), [override])
    assert cfg.mrf.method == method and len(caught) == warned


def test_run_with_the_old_key_warns_in_one_line_and_writes_the_new_one(tmp_path, capsys):
    out = tmp_path / "o"
    rc = main(["run", str(EXPERIMENTS / "corridor.toml"), "--out", str(out), "--set", "mrf.optimizer=gibbs",
               *[a for s in QUICK for a in ("--set", s)]])
    err = [line for line in capsys.readouterr().err.splitlines() if "optimizer" in line]  # (QUICK: max_steps said)
    assert rc == 0
    assert err == ["mrfswarm: warning: config key mrf.optimizer is now mrf.method; mrf.optimizer still loads, as "
                   "mrf.method"]
    res = json.loads((out / "result.json").read_text())
    assert res["mrf"] == "gibbs" and res["config"]["mrf"]["method"] == "gibbs" and "optimizer" not in res["config"]["mrf"]


def test_an_unknown_method_is_one_line_naming_it(tmp_path, capsys):
    rc = main(["run", str(EXPERIMENTS / "corridor.toml"), "--out", str(tmp_path / "o"), "--set", "mrf.method=nope"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and err[0].startswith("mrfswarm: error: ") and "'nope'" in err[0], err
    assert not (tmp_path / "o").exists()


def test_an_unused_qp_flag_is_said(tmp_path):
    """--qp with the continuous stage off went unused without a word, where an unused --nlp is said (a tour)."""
    cfg = load_config(EXPERIMENTS / "free5.toml", ["smoothing.enabled=false"])
    with pytest.warns(UnusedSettingWarning, match="^QP backend 'osqp' not used: the continuous stage is off$"):
        resolve_config(cfg, qp="osqp")


@pytest.mark.parametrize("config, sets, said", [
    ("window3d.toml", ["scenario.altitude=1.5"], "scenario.altitude = 1.5 not used: on a 3-D map"),
    ("free5.toml", ["scenario.downwash=2.5"], "scenario.downwash = 2.5 not used: on a 2-D map"),
    ("window3d.toml", [], None), ("free5.toml", ["scenario.altitude=1.5"], None),
])
def test_a_scenario_setting_the_maps_dimension_leaves_unused_is_said(config, sets, said):
    """altitude on a 3-D map, downwash on a 2-D one: accepted without a word (a 3-D tour)."""
    import warnings

    from mrfswarm import pipeline

    cfg = load_config(EXPERIMENTS / config, sets)
    dim = 3 if "3d" in config else 2
    if said is None:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            pipeline._unused_scenario_settings(cfg, dim)
    else:
        with pytest.warns(UnusedSettingWarning, match=f"^{said}"):
            pipeline._unused_scenario_settings(cfg, dim)


def test_plan_says_an_unused_scenario_setting(monkeypatch):
    """The check runs inside plan, once the map is loaded (its dimension is the map's)."""
    from mrfswarm import pipeline

    monkeypatch.setattr(pipeline, "mrf_options", lambda cfg: (_ for _ in ()).throw(RuntimeError("stop here")))
    with pytest.warns(UnusedSettingWarning, match="scenario.downwash = 2 not used"), pytest.raises(RuntimeError):
        pipeline.plan(load_config(EXPERIMENTS / "free5.toml", ["scenario.downwash=2"]))


@pytest.mark.parametrize("flag, name, sets", [("--mrf", "exact", ["mrf.method=exact"]),
                                              ("--qp", "osqp", ["smoothing.backend=osqp"]),
                                              # naming an NLP backend asks for the NLP refinement
                                              ("--nlp", "slsqp", ["smoothing.nlp=slsqp", "smoothing.refinement=nlp"])])
def test_mrf_qp_and_nlp_flags_are_shorthands_for_set(flag, name, sets):
    # free5 does not refine: the NLP backend named is not used, and a warning says so
    with pytest.warns(UnusedSettingWarning, match="not used") if flag == "--nlp" else contextlib.nullcontext():
        by_flag = resolve_config(load_config(EXPERIMENTS / "free5.toml"), **{flag.strip("-"): name})
    by_set = resolve_config(load_config(EXPERIMENTS / "free5.toml", sets))
    assert by_flag == by_set and by_flag != load_config(EXPERIMENTS / "free5.toml")
    if flag == "--nlp":  # the one key alone is not the same: the refinement method stays the scaling (and says so)
        with pytest.warns(UnusedSettingWarning, match="smoothing.nlp = 'slsqp' not used: smoothing.refinement is "
                                                      "'scaling'"):
            alone = resolve_config(load_config(EXPERIMENTS / "free5.toml", sets[:1]))
        assert by_flag != alone


def test_the_nlp_key_without_the_nlp_refinement_is_said_unused():
    """smoothing.nlp set, refinement left the scaling: a tour's refined run used the scaling, result.json said
    nlp: null, and nothing was printed. The default backend, or the refinement "nlp", says nothing."""
    import warnings

    sets = ["smoothing.time_refinement=true"]
    with pytest.warns(UnusedSettingWarning, match=r"give --nlp cobyqa|give --nlp slsqp"):
        resolve_config(load_config(EXPERIMENTS / "free5.toml", [*sets, "smoothing.nlp=slsqp"]))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        resolve_config(load_config(EXPERIMENTS / "free5.toml", sets))
        resolve_config(load_config(EXPERIMENTS / "free5.toml", [*sets, "smoothing.nlp=slsqp",
                                                                 "smoothing.refinement=nlp"]))


def test_a_sweep_over_the_old_key_tabulates_the_new_name(tmp_path):
    with pytest.warns(DeprecatedKeyWarning):
        res = run_sweep(EXPERIMENTS / "free5.toml", {"mrf.optimizer": ["icm", "exact"]}, tmp_path / "s", workers=1,
                        progress=False, overrides=QUICK)
    assert "mrf.method" in res.columns and "mrf.optimizer" not in res.columns
    assert [r["mrf.method"] for r in res.rows] == [r["mrf"] for r in res.rows] == ["icm", "exact"]
    header = (tmp_path / "s" / "sweep.csv").read_text().splitlines()[0].split(",")
    assert "mrf.method" in header and "mrf.optimizer" not in header


def test_a_sweep_given_both_names_fails_before_running(tmp_path):
    with pytest.warns(DeprecatedKeyWarning), pytest.raises(ConfigError, match=r"grid mrf\.optimizer: mrf\.method is "
                                                                             r"given twice"):
        run_sweep(EXPERIMENTS / "free5.toml", {"mrf.method": ["icm"], "mrf.optimizer": ["exact"]}, tmp_path / "s",
                  workers=1, progress=False, overrides=QUICK)
    assert not (tmp_path / "s").exists()


# --- solver options from the config: [mrf.options], [smoothing.qp_options] ----------------------


def test_mrf_options_reach_the_mrf_method(tmp_path):
    """One ICM sweep per step: the reported iterations and the paths change."""
    corridor = (EXPERIMENTS / "corridor.toml").read_text() + "\n[mrf.options]\nmax_iter = 1\n"
    capped = plan(load_config(write(tmp_path, corridor), ["smoothing.enabled=false", "mrf.max_steps=10"]),
                  progress=False)
    default = plan(load_config(EXPERIMENTS / "corridor.toml", ["smoothing.enabled=false", "mrf.max_steps=10"]), progress=False)
    assert capped.config.mrf.options == {"max_iter": 1}
    assert max(s["iterations"] for s in default.discrete.steps) > 1
    assert {s["iterations"] for s in capped.discrete.steps} == {1}
    assert not np.array_equal(default.discrete.paths, capped.discrete.paths)


def test_mrf_options_merge_under_the_seed():
    cfg = load_config(None, ["mrf.options.max_iter=5", "mrf.options.seed=7", 'mrf.options.schedule="log"'])
    assert cfg.mrf.options == {"max_iter": 5, "seed": 7, "schedule": "log"}
    assert mrf_options(cfg) == mrf.Options(max_iter=5, seed=7, schedule="log")
    assert mrf_options(cfg, seed=3) == mrf.Options(max_iter=5, seed=3, schedule="log")  # plan(seed=) wins
    assert mrf_options(load_config(None)) == mrf.Options()


def test_qp_options_go_over_the_stages_own_and_reach_every_solve(monkeypatch):
    cfg = load_config(EXPERIMENTS / "free5.toml", ["simulation.enabled=false", "mrf.max_steps=3",
                                           "smoothing.qp_options.eps_abs=1e-6", "smoothing.qp_options.max_iter=777"])
    expected = dataclasses.replace(QP_OPTIONS, eps_abs=1e-6, max_iter=777)
    assert qp_options(cfg) == expected and expected.eps_rel == QP_OPTIONS.eps_rel != expected.eps_abs
    assert qp_options(load_config(None)) == QP_OPTIONS
    seen = []
    solve = solvers.qp.PreparedQP.solve

    def recording(self, warm_start=None):  # every solve, set up afresh or updated in place (window_cache)
        seen.append(self.options)
        return solve(self, warm_start)

    monkeypatch.setattr(solvers.qp.PreparedQP, "solve", recording)
    # the faster profiles rash (cruise 1.5 v_max, 4 times their acceleration: they have no solution) and no
    # stretched attempts (which run the smaller budget and fly this window): the cautious profile flies it, on the
    # whole budget (the default flies it fast, on the smaller one only)
    monkeypatch.setattr(receding_horizon, "STRETCH_POWERS", ())
    monkeypatch.setattr(receding_horizon, "PROFILES", tuple(
        p if p[0] == "cautious" else (p[0], 1.5, 4 * p[2]) for p in receding_horizon.PROFILES))
    plan(cfg, progress=False, workers=1)
    # the bold and moderate attempts run a third of the budget PIQP gives (its cap of 120 under 777)
    optimistic = dataclasses.replace(expected, max_iter=40)
    assert seen and all(o in (expected, optimistic) for o in seen) and expected in seen


def test_set_reaches_the_options_tables_from_the_cli(tmp_path):
    out = tmp_path / "o"
    rc = main(["run", str(EXPERIMENTS / "free5.toml"), "--out", str(out), "--set", "mrf.options.max_iter=5",
               "--set", "smoothing.qp_options.verbose=false", *[a for s in QUICK for a in ("--set", s)]])
    assert rc == 0
    res = json.loads((out / "result.json").read_text())
    assert res["config"]["mrf"]["options"] == {"max_iter": 5}
    assert res["config"]["smoothing"]["qp_options"] == {"verbose": False}


@pytest.mark.parametrize("override, message", [
    ("mrf.options.max_itr=5", "unknown config key mrf.options.max_itr; allowed: max_iter, tol, seed"),
    ('mrf.options.max_iter="many"', "mrf.options.max_iter must be an integer, got 'many'"),
    ("mrf.options.max_iter=2.5", "mrf.options.max_iter must be an integer, got 2.5"),
    ("mrf.options.polish=1", "mrf.options.polish must be true or false, got 1"),
    ("mrf.options.max_iter=0", "mrf.options: max_iter must be >= 1, got 0"),
    ("mrf.options.seed=-3", "mrf.options: seed must be >= 0, got -3"),
    ("smoothing.qp_options.scaling=3", "smoothing.qp_options.scaling must be true or false, got 3"),
    ('mrf.options.schedule="linear"', "mrf.options: schedule must be 'geometric' or 'log', got 'linear'"),
    ("mrf.options=3", "mrf.options must be a table, got 3"),
    ("smoothing.qp_options.eps=1e-6", "unknown config key smoothing.qp_options.eps; allowed: eps_abs, eps_rel"),
    ("smoothing.qp_options.eps_abs=true", "smoothing.qp_options.eps_abs must be a number, got True"),
    ("smoothing.qp_options.time_limit=-1", "smoothing.qp_options: time_limit must be positive, got -1"),
    ("scenario.downwash=0.5", "scenario.downwash = 0.5: must be in [1, 20]"),
    ("scenario.downwash=inf", "scenario.downwash must be finite, got inf"),
    # huge values exhausted the memory, hung or overflowed (a robustness tour); each bound far past any use
    ("scenario.downwash=1000", "scenario.downwash = 1000.0: must be in [1, 20]"),
    ("scenario.altitude=1e300", "scenario.altitude = 1e+300: must be in (0, 10000] (metres)"),
    ("obstacle_potential.sigma=99999999999", "obstacle_potential.sigma = 99999999999.0: must be in [0, 1000] (cells)"),
    ("mrf.order=100", "mrf.order = 100: must be in 1..32"),
    ("mrf.tol=2", "mrf.tol = 2.0: must be in [0, 1) (a fraction of the swarm energy)"),
    ("smoothing.region_growth=1e11", "smoothing.region_growth = 100000000000.0: must be in [0, 1000] (cells)"),
    ("smoothing.check_rate_hz=1e11", "smoothing.check_rate_hz = 100000000000.0: must be 0 (off) or in [100, 10000]"),
    # a degree the run's own outputs cannot hold is refused before planning, not after it
    ("smoothing.degree=9", "smoothing.degree = 9: must be <= 7"),
    ("smoothing.derivative=5", "smoothing.derivative = 5: must be in 1..4"),
    # a cruise speed above the limit was accepted and flew slower than the default (its steps stretched)
    ("smoothing.speed=5", "smoothing.speed = 5.0: must be <= smoothing.v_max = 2"),
])
def test_bad_solver_options_are_one_line_naming_the_key(tmp_path, capsys, override, message):
    with pytest.raises(ConfigError) as e:
        load_config(EXPERIMENTS / "free5.toml", [override])
    assert str(e.value).startswith(message) and "\n" not in str(e.value), str(e.value)
    rc = main(["run", str(EXPERIMENTS / "free5.toml"), "--out", str(tmp_path / "o"), "--set", override])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and err[0].startswith(f"mrfswarm: error: {message}"), err


def test_a_config_saved_with_a_byte_order_mark_is_read(tmp_path):
    """Some editors save UTF-8 with a byte-order mark: TOML refused it, "Invalid statement (line 1, column 1)"."""
    path = tmp_path / "bom.toml"
    path.write_bytes(b"\xef\xbb\xbf" + (EXPERIMENTS / "free5.toml").read_bytes())
    assert load_config(path) == load_config(EXPERIMENTS / "free5.toml")


def test_the_nlp_key_is_checked_against_the_registry(tmp_path):
    """``smoothing.nlp`` names a backend of ``solvers.nlp.BACKENDS``: one line naming the value and
    every registered name, from a file, from ``plan(nlp=)``, and the default is registered."""
    import solvers.nlp

    allowed = ", ".join(solvers.nlp.BACKENDS.names())
    with pytest.raises(ConfigError, match=rf"^smoothing\.nlp = 'newton': must be one of {allowed}$"):
        load_config(write(tmp_path, '[smoothing]\nnlp = "newton"\n'))
    with pytest.raises(ConfigError, match=r"^smoothing\.nlp = 'newton': must be one of ipopt"):
        plan(EXPERIMENTS / "free5.toml", nlp="newton")
    assert load_config().smoothing.nlp == solvers.nlp.DEFAULT_BACKEND == "ipopt"
    for name in solvers.nlp.BACKENDS.names():
        assert load_config(write(tmp_path, f'[smoothing]\nnlp = "{name}"\n')).smoothing.nlp == name


@pytest.mark.parametrize("override, table, expected", [
    ("scenario.map.size=[12,12]", "map", {"kind": "free", "size": [12, 12]}),
    ("scenario.start.n_robots=6", "start", {"center": [5.0, 5.0], "n_robots": 6, "seed": 0}),
    ("scenario.start.positions=[[1,1],[3,3]]", "start", {"positions": [[1, 1], [3, 3]]}),  # not a default key
    ("scenario.map.kind=free", "map", {"kind": "free", "size": [20, 20]}),  # the default's own kind
])
def test_a_key_of_a_table_left_to_its_default_sets_it_in_the_default_table(override, table, expected):
    assert getattr(load_config(None, [override]).scenario, table) == expected


def test_another_kind_than_the_default_maps_starts_a_table_of_its_own():
    """``--set scenario.map.kind=ascii`` was refused as 'unknown key scenario.map.size', a key of the default
    free map the user never wrote (new-user tour); the ASCII map's own required key is asked for instead."""
    assert apply_overrides({}, ["scenario.map.kind=ascii"]) == {"scenario": {"map": {"kind": "ascii"}}}
    with pytest.raises(ConfigError, match=r"^scenario\.map\.rows is missing"):
        build_scenario(load_config(None, ["scenario.map.kind=ascii"]))
    rows = load_config(None, ["scenario.map.kind=ascii", 'scenario.map.rows=["....", "...."]']).scenario.map
    assert rows == {"kind": "ascii", "rows": ["....", "...."]}


def test_a_key_of_a_table_the_config_gives_sets_it_in_that_table(tmp_path):
    cfg = load_config(write(tmp_path, '[scenario]\nstart = { center = [8, 8], n_robots = 4 }\n'),
                      ["scenario.start.n_robots=6"])
    assert cfg.scenario.start == {"center": [8, 8], "n_robots": 6}
    assert apply_overrides({}, ["smoothing.v_max=3"]) == {"smoothing": {"v_max": 3}}  # sections stay sparse


@pytest.mark.parametrize("config", [5, {"scenario": {}}, ["c.toml"]])
def test_a_config_that_is_neither_a_path_nor_a_config_is_a_config_error(config):
    import mrfswarm

    with pytest.raises(ConfigError, match=r"^a config is a path to a TOML file \(or, to plan, a Config object\), got"):
        load_config(config)
    with pytest.raises(ConfigError, match="a config is a path to a TOML file"):
        mrfswarm.plan(config)


def test_numpy_values_in_a_config_dict_are_plain_values():
    """A researcher builds starts with NumPy: an array of positions was refused in a six-line message, and
    ``np.int64(2)`` as k as "not an integer"."""
    import numpy as np

    from mrfswarm.config import from_dict

    positions = np.array([[2.0, 2.0], [2.0, 4.0], [4.0, 2.0], [4.0, 4.0]])
    cfg = from_dict({"scenario": {"map": {"kind": "free", "size": [20, 20]}, "goal": np.array([15, 10]),
                                  "start": {"positions": positions}},
                     "interaction": {"k": np.int64(2)}, "smoothing": {"v_max": np.float64(1.5)}})
    assert cfg.interaction.k == 2 and type(cfg.interaction.k) is int and cfg.smoothing.v_max == 1.5
    assert [list(p) for p in cfg.scenario.start["positions"]] == positions.tolist()


def test_overrides_given_as_one_string_are_refused():
    with pytest.raises(ConfigError, match=r"^overrides = 'interaction.k=2': a list of 'KEY=VALUE' strings"):
        load_config(None, overrides="interaction.k=2")  # type: ignore[arg-type]


@pytest.mark.parametrize(("start", "k"), [
    ({"positions": [[1, 1], [2, 1]]}, 1),
    ({"center": [5, 5], "n_robots": 3, "seed": 0}, 2),
    ({"center": [5, 5], "n_robots": 4, "seed": 0}, 3),
    ({"center": [5, 5], "n_robots": 40, "seed": 0}, 3),
])
def test_the_default_k_fits_a_small_swarm(start, k):
    """The default k = 3 needs 4 robots: a swarm of 2 was refused with 'interaction.k = 3: must satisfy
    1 <= k < N = 2', a key its user never set (new-user tour)."""
    cfg = from_dict({"scenario": {"map": {"kind": "free", "size": [10, 10]}, "start": start, "goal": [8, 8]}})
    assert cfg.interaction.k == k
    build_scenario(cfg)


def test_a_k_the_user_set_is_kept_and_checked():
    cfg = from_dict({"scenario": {"map": {"kind": "free", "size": [10, 10]}, "start": {"positions": [[1, 1], [2, 1]]},
                                  "goal": [8, 8]}, "interaction": {"k": 3}})
    assert cfg.interaction.k == 3
    with pytest.raises(ConfigError, match=r"interaction.k = 3: must satisfy 1 <= k < N = 2"):
        build_scenario(cfg)


def test_one_free_cell_is_one_cell(tmp_path):
    with pytest.raises(ScenarioError, match=r"the map has only 1 free cell$"):
        build_scenario(from_dict({"scenario": {"map": {"kind": "ascii", "rows": ["#.#"]},
                                               "start": {"center": [1, 0], "n_robots": 2}, "goal": [1, 0]}}))
