"""The config: one name per solver choice (``mrf.method``, ``smoothing.backend``), old names that still load."""

import json
import warnings
from pathlib import Path

import pytest

from mrfswarm.cli import main
from mrfswarm.config import from_dict, load_config
from mrfswarm.errors import ConfigError, DeprecatedKeyWarning
from mrfswarm.pipeline import resolve_config
from mrfswarm.sweep import run_sweep

EXP = Path(__file__).resolve().parents[1] / "experiments"
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
    rc = main(["run", str(EXP / "corridor.toml"), "--out", str(out), "--set", "mrf.optimizer=gibbs",
               *[a for s in QUICK for a in ("--set", s)]])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 0
    assert err == ["mrfswarm: warning: config key mrf.optimizer is now mrf.method; mrf.optimizer still loads, as "
                   "mrf.method"]
    res = json.loads((out / "result.json").read_text())
    assert res["mrf"] == "gibbs" and res["config"]["mrf"]["method"] == "gibbs" and "optimizer" not in res["config"]["mrf"]


def test_an_unknown_method_is_one_line_naming_it(tmp_path, capsys):
    rc = main(["run", str(EXP / "corridor.toml"), "--out", str(tmp_path / "o"), "--set", "mrf.method=nope"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and err[0].startswith("mrfswarm: error: ") and "'nope'" in err[0], err
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("flag, key, name", [("--mrf", "mrf.method", "exact"),
                                             ("--qp", "smoothing.backend", "osqp")])
def test_mrf_and_qp_flags_are_shorthands_for_set(flag, key, name):
    by_flag = resolve_config(load_config(EXP / "free5.toml"), **{flag.strip("-"): name})
    by_set = resolve_config(load_config(EXP / "free5.toml", [f"{key}={name}"]))
    assert by_flag == by_set and by_flag != load_config(EXP / "free5.toml")


def test_a_sweep_over_the_old_key_tabulates_the_new_name(tmp_path):
    with pytest.warns(DeprecatedKeyWarning):
        res = run_sweep(EXP / "free5.toml", {"mrf.optimizer": ["icm", "exact"]}, tmp_path / "s", workers=1,
                        progress=False, overrides=QUICK)
    assert "mrf.method" in res.columns and "mrf.optimizer" not in res.columns
    assert [r["mrf.method"] for r in res.rows] == [r["mrf"] for r in res.rows] == ["icm", "exact"]
    header = (tmp_path / "s" / "sweep.csv").read_text().splitlines()[0].split(",")
    assert "mrf.method" in header and "mrf.optimizer" not in header


def test_a_sweep_given_both_names_fails_before_running(tmp_path):
    with pytest.warns(DeprecatedKeyWarning), pytest.raises(ConfigError, match=r"grid mrf\.optimizer: mrf\.method is "
                                                                             r"given twice"):
        run_sweep(EXP / "free5.toml", {"mrf.method": ["icm"], "mrf.optimizer": ["exact"]}, tmp_path / "s",
                  workers=1, progress=False, overrides=QUICK)
    assert not (tmp_path / "s").exists()
