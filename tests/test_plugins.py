"""Backends added from outside the package, used as a user would: a script's ``register`` reaching a sweep's
spawned workers, and an installed distribution's entry point reaching ``mrfswarm solvers``, ``run`` and ``sweep``."""

import json
import os
import subprocess
import sys
import textwrap

import pytest

from support.repository import EXPERIMENTS

FREE5 = EXPERIMENTS / "free5.toml"
FAST = ["smoothing.enabled=false", "mrf.max_steps=6"]

SCRIPT = """
import json
import sys

from solvers.mrf import METHODS, icm
from solvers.registry import Backend


def icm_twin(mrf, options):
    return icm.minimize(mrf, options)


if __name__ == "__main__":
    METHODS.register(Backend(name="icm_twin", entry=icm_twin, capabilities=icm.BACKEND.capabilities))
    from mrfswarm.sweep import run_sweep

    res = run_sweep(sys.argv[1], {"mrf.method": ["icm", "icm_twin"], "interaction.k_a": [10, 14]}, sys.argv[2],
                    workers=2, overrides=%r)
    print(json.dumps([r["error"] for r in res.rows]))
"""


def _columns(path):
    import csv

    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def test_a_scripts_registered_method_reaches_the_sweeps_spawned_workers(tmp_path):
    script = tmp_path / "sweep_twin.py"
    script.write_text(textwrap.dedent(SCRIPT % FAST))
    out = subprocess.run([sys.executable, str(script), str(FREE5), str(tmp_path / "sweep")], capture_output=True,
                         text=True, timeout=600, check=True)
    assert json.loads(out.stdout.strip().splitlines()[-1]) == [None] * 4  # "unknown MRF method 'icm_twin'" before
    rows = _columns(tmp_path / "sweep" / "sweep.csv")
    plain = {r["interaction.k_a"]: r for r in rows if r["mrf.method"] == "icm"}
    for r in rows:  # the same method under another name: the same plans
        if r["mrf.method"] == "icm_twin":
            assert r["mrf_steps"] == plain[r["interaction.k_a"]]["mrf_steps"]
            assert r["makespan_s"] == plain[r["interaction.k_a"]]["makespan_s"]


PLUGIN = """
from solvers.mrf import icm
from solvers.registry import Backend

BACKEND = Backend(name="icm_plugin", entry=icm.minimize, summary="ICM from a plugin",
                  capabilities=icm.BACKEND.capabilities)
"""


def test_an_installed_entry_point_is_listed_run_and_swept(tmp_path):
    site = tmp_path / "site"
    info = site / "swarm_plugins-0.1.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: swarm_plugins\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text("[solvers.mrf]\nicm_plugin = swarm_icm:BACKEND\n")
    (site / "swarm_icm.py").write_text(PLUGIN)
    env = os.environ | {"PYTHONPATH": os.pathsep.join([str(site), os.environ.get("PYTHONPATH", "")])}
    cli = [sys.executable, "-m", "mrfswarm.cli"]

    listing = subprocess.run([*cli, "solvers"], capture_output=True, text=True, env=env, check=True).stdout
    line = next(ln for ln in listing.splitlines() if ln.strip().startswith("icm_plugin"))
    assert "installed, added by swarm_plugins" in line and "ICM from a plugin" in line

    sets = [a for s in FAST for a in ("--set", s)]
    subprocess.run([*cli, "run", str(FREE5), "--mrf", "icm_plugin", *sets, "--out", str(tmp_path / "run")],
                   capture_output=True, text=True, env=env, check=True)
    assert json.loads((tmp_path / "run" / "result.json").read_text())["config"]["mrf"]["method"] == "icm_plugin"

    subprocess.run([*cli, "sweep", str(FREE5), "--grid", "mrf.method=icm,icm_plugin", *sets, "--workers", "2",
                    "--out", str(tmp_path / "sweep")], capture_output=True, text=True, env=env, check=True)
    rows = _columns(tmp_path / "sweep" / "sweep.csv")
    assert [r["error"] for r in rows] == ["", ""] and rows[0]["mrf_steps"] == rows[1]["mrf_steps"]


def test_a_record_the_workers_cannot_import_is_refused_before_the_sweep(tmp_path):
    """A lambda registered in a script: the workers' start failed with a pickling traceback and left an empty output
    folder (a tour); now one line naming the backend, before anything is written."""
    from mrfswarm.errors import ConfigError
    from mrfswarm.sweep import run_sweep
    from solvers.mrf import METHODS, icm
    from solvers.registry import Backend

    METHODS.register(Backend(name="icm_lambda", entry=lambda m, o: icm.minimize(m, o),
                             capabilities=icm.BACKEND.capabilities))
    try:
        with pytest.raises(ConfigError, match=r"^backend 'icm_lambda' \(solvers\.mrf\), registered in this process, "
                                              "cannot reach the sweep's worker processes"):
            run_sweep(FREE5, {"mrf.method": ["icm", "icm_lambda"]}, tmp_path / "out", workers=2, overrides=FAST)
        assert not (tmp_path / "out").exists()
        one = run_sweep(FREE5, {"mrf.method": ["icm", "icm_lambda"]}, tmp_path / "one", workers=1, overrides=FAST)
        assert [r["error"] for r in one.rows] == [None, None]  # in this process it is known
    finally:
        METHODS.unregister("icm_lambda")


INTERACTIVE = """
from solvers.mrf import METHODS, icm
from solvers.registry import Backend
from mrfswarm.errors import ConfigError
from mrfswarm.sweep import run_sweep


def icm_cell(mrf, options):
    return icm.minimize(mrf, options)


METHODS.register(Backend(name="icm_cell", entry=icm_cell, capabilities=icm.BACKEND.capabilities))
try:
    run_sweep({config!r}, {{"mrf.method": ["icm", "icm_cell"]}}, {out!r}, workers=2, overrides={fast!r})
except ConfigError as e:
    print(e)
"""


def test_a_record_defined_in_an_interactive_session_is_refused_before_the_sweep(tmp_path):
    """docs/extending.md: a notebook cell's entry is refused in one line before the sweep starts. One defined in
    `python -c` (a main module without a file, as a notebook's) pickled by reference, and the spawned workers died
    with "Can't get attribute 'icm_cell' on <module '__main__'>": a BrokenProcessPool traceback saying the script
    lacked `if __name__ == "__main__":`."""
    code = INTERACTIVE.format(config=str(FREE5), out=str(tmp_path / "out"), fast=FAST)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.startswith("backend 'icm_cell' (solvers.mrf), registered in this process, cannot reach the "
                                 "sweep's worker processes: its entry is not importable by reference (icm_cell is "
                                 "defined in an interactive session"), out.stdout
    assert not (tmp_path / "out").exists()
