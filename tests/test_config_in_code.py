"""A config built or changed in Python is checked as a file is (a library tour, 2026-11-30).

``Config.replace`` with ``dataclasses.replace`` of a section skipped every check of ``from_dict``: a negative
``v_max`` ended in "math domain error" inside the continuous stage, ``seam = "bogus"`` planned without a word, a
string radius in "'<' not supported between instances of 'str' and 'float'".
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

import mrfswarm
from mrfswarm import pipeline
from mrfswarm.config import Config, from_dict, load_config, validated
from mrfswarm.errors import ConfigError

EXPERIMENTS = Path(__file__).resolve().parents[1] / "experiments"
BASE = {"scenario": {"map": {"kind": "ascii", "rows": ["......", "..#...", "......"]},
                     "start": {"positions": [[0, 0], [0, 2]]}, "goal": [5, 1], "robot_radius": 0.3},
        "simulation": {"enabled": False}}


@pytest.fixture
def no_scenario(monkeypatch):
    def refuse(*args, **kwargs):
        raise AssertionError("the scenario was built before the config was checked")

    monkeypatch.setattr(pipeline, "build_scenario", refuse)


@pytest.mark.parametrize(("section", "key", "value", "message"), [
    ("smoothing", "v_max", -1.0, r"^smoothing\.v_max = -1\.0: must be > 0"),
    ("smoothing", "seam", "bogus", r"^smoothing\.seam = 'bogus': must be one of"),
    ("smoothing", "horizon", 0, r"^smoothing\.horizon = 0: must be >= 1"),
    ("scenario", "robot_radius", "0.3", r"^scenario\.robot_radius must be a number, got '0\.3'"),
    ("scenario", "robot_radius", -0.3, r"^scenario\.robot_radius = -0\.3: must be > 0"),
    ("mrf", "max_steps", 0, r"^mrf\.max_steps = 0: must be >= 1"),
])
def test_a_config_changed_in_code_is_checked_before_planning(no_scenario, section, key, value, message):
    cfg = from_dict(BASE)
    bad = cfg.replace(**{section: dataclasses.replace(getattr(cfg, section), **{key: value})})
    with pytest.raises(ConfigError, match=message):
        mrfswarm.plan(bad)


def test_validated_keeps_every_experiment_config():
    for path in sorted(EXPERIMENTS.glob("**/*.toml")):
        cfg = load_config(path)
        again = validated(cfg)
        assert again == cfg, path
        assert again.base_dir == cfg.base_dir


def test_a_config_built_by_hand_is_checked():
    with pytest.raises(ConfigError, match=r"^\[scenario\] must be a table, got 5"):
        validated(Config(scenario=5))


@pytest.mark.parametrize("data", [[1, 2], "scenario"])
def test_config_data_that_is_not_a_table_is_a_config_error(data):
    with pytest.raises(ConfigError, match=r"^a config's data is a table of sections"):
        from_dict(data)


def test_a_dict_given_to_plan_names_from_dict():
    with pytest.raises(ConfigError, match=r"mrfswarm\.config\.from_dict\(data\)$"):
        mrfswarm.plan(BASE)


def test_an_escalation_method_that_is_not_installed_fails_before_planning(no_scenario, monkeypatch):
    """It failed at the first step the planner escalated, after part of the discrete stage (a library tour)."""
    import solvers.mrf
    from solvers.errors import SolverNotFound
    from solvers.registry import Backend, Registry

    icm = solvers.mrf.METHODS.get("icm")
    ghost = Backend(name="ghost_mrf", entry=icm.entry, requires=("no_such_module_xyz",), extra="ghost",
                    capabilities=icm.capabilities)
    registry = Registry("MRF", [*solvers.mrf.METHODS, ghost], noun="method")
    monkeypatch.setattr(solvers.mrf, "METHODS", registry)
    monkeypatch.setattr(pipeline.mrf_solvers, "METHODS", registry)
    monkeypatch.setattr("mrfswarm.config.MRF_METHODS", registry)
    cfg = from_dict({**BASE, "mrf": {"escalation": "ghost_mrf"}})
    with pytest.raises(SolverNotFound, match=r"^mrf\.escalation: MRF method 'ghost_mrf' is not installed"):
        mrfswarm.plan(cfg)


def test_a_map_given_as_an_array_is_refused_in_a_short_line_that_says_how():
    """A researcher's occupancy array as ``scenario.map`` was refused with the whole array in the message (17,000
    characters for 60 x 40 cells; a library tour); the line is now short and says to save it as an npy map."""
    occ = np.zeros((60, 40), dtype=bool)
    with pytest.raises(ConfigError, match=r"^scenario\.map must be a table, got \[\[False, .*\.\.\.; an occupancy "
                                          r"array is read from a file: numpy\.save it and give \{\"kind\": \"npy\"") as e:
        from_dict({"scenario": {"map": occ}})
    assert len(str(e.value)) < 250
    with pytest.raises(ConfigError, match=r"^smoothing\.v_max must be a number, got \[0, 1, .*\.\.\.$") as e:
        from_dict({"smoothing": {"v_max": list(range(1000))}})
    assert len(str(e.value)) < 150


def test_build_scenario_alone_checks_its_config_and_seed():
    """Stage by stage (build_scenario, then plan_discrete), a dict ended in "'dict' object has no attribute
    'scenario'", a negative robot radius set in code gave a scenario, a string seed NumPy's "SeedSequence expects
    int or sequence of ints" (a library tour)."""
    cfg = Config()
    with pytest.raises(ConfigError, match=r"^expected a Config, got dict"):
        mrfswarm.build_scenario({"scenario": {}})
    with pytest.raises(ConfigError, match=r"^scenario\.robot_radius = -1\.0: must be > 0"):
        mrfswarm.build_scenario(cfg.replace(scenario=dataclasses.replace(cfg.scenario, robot_radius=-1.0)))
    for seed in ("a", -1, True):
        with pytest.raises(ConfigError, match=rf"^seed = {seed!r}: must be an integer >= 0$"):
            mrfswarm.build_scenario(cfg, seed=seed)
    assert mrfswarm.build_scenario(cfg, seed=np.int64(3)).start.tolist() == mrfswarm.build_scenario(cfg, 3).start.tolist()
