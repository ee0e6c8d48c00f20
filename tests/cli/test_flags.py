"""Every flag of every subcommand: a bad value is one line on stderr and exit 2, nothing written."""

import re
import subprocess
import sys

import pytest

from mrfswarm.cli import main
from support.repository import EXPERIMENTS

FREE5 = str(EXPERIMENTS / "free5.toml")
CORRIDOR = str(EXPERIMENTS / "corridor.toml")

# (argv after the program name, a pattern of the one-line message); FILE is a regular file,
# OUT a fresh folder, WP a waypoints CSV
BAD = {
    "run --seed negative": (["run", FREE5, "--seed", "-5", "--out", "OUT"], "argument --seed: must be an integer >= 0, got '-5'"),
    "run --seed text": (["run", FREE5, "--seed", "x", "--out", "OUT"], "argument --seed: must be an integer >= 0"),
    "run --out a file": (["run", FREE5, "--out", "FILE"], "argument --out: .* is a file, not a folder"),
    "run --out under a file": (["run", FREE5, "--out", "FILE/sub"], "argument --out: .* lies under the file"),
    "run --mrf unknown": (["run", FREE5, "--mrf", "nope", "--out", "OUT"], "error: mrf.method: unknown MRF method 'nope'"),
    "run --qp unknown": (["run", FREE5, "--qp", "nope", "--out", "OUT"], "error: smoothing.backend: unknown QP backend 'nope'"),
    "run --set mrf.method unknown": (["run", FREE5, "--set", "mrf.method=nope", "--out", "OUT"],
                                     "error: mrf.method: unknown MRF method 'nope'; installed: icm, "),
    "run --qp unknown, smoothing off": (["run", FREE5, "--qp", "nope", "--set", "smoothing.enabled=false", "--out", "OUT"],
                                        "error: smoothing.backend: unknown QP backend 'nope'"),
    "run unknown vehicle, simulation off": (["run", FREE5, "--set", "simulation.vehicle=foo", "--set",
                                             "simulation.enabled=false", "--out", "OUT"],
                                            "simulation.vehicle = 'foo': must be one of crazyflie"),
    "run --qp equality-only": (["run", CORRIDOR, "--qp", "closed_form", "--out", "OUT"],
                               r"smoothing.backend = 'closed_form' solves equality-constrained problems only; .* "
                               r"\(installed backends that take them: osqp, piqp"),
    "run --nlp unknown": (["run", FREE5, "--nlp", "nope", "--out", "OUT"],
                          "smoothing.nlp = 'nope': must be one of ipopt, sqpmethod, slsqp, trust_constr, lbfgsb"),
    "run --set smoothing.nlp unknown": (["run", FREE5, "--set", "smoothing.nlp=nope", "--out", "OUT"],
                                        "smoothing.nlp = 'nope': must be one of ipopt, sqpmethod"),
    "run --set no value": (["run", FREE5, "--set", "mrf.order", "--out", "OUT"], "expected KEY=VALUE"),
    "run --set bad distance": (["run", FREE5, "--set", "goal_potential.distance=manhattan", "--out", "OUT"],
                               "goal_potential.distance = 'manhattan': must be one of geodesic, euclidean"),
    "run start seed negative": (["run", FREE5, "--set", "scenario.start.seed=-3", "--out", "OUT"],
                                r"scenario.start.seed = -3: must be an integer >= 0"),
    "run config missing": (["run", "nowhere.toml", "--out", "OUT"], "cannot read config"),
    "sweep --seeds negative": (["sweep", FREE5, "--grid", "mrf.order=1", "--out", "OUT", "--seeds", "0,-5"],
                               "--seeds '0,-5': '-5' must be an integer >= 0"),
    "sweep --seeds text": (["sweep", FREE5, "--grid", "mrf.order=1", "--out", "OUT", "--seeds", "1.5"], "is not an integer"),
    "sweep --workers zero": (["sweep", FREE5, "--grid", "mrf.order=1", "--out", "OUT", "--workers", "0"],
                             "--workers 0: must be an integer >= 1"),
    "sweep --workers text": (["sweep", FREE5, "--grid", "mrf.order=1", "--out", "OUT", "--workers", "two"],
                             "argument --workers: invalid int value: 'two'"),
    "sweep --connect-timeout negative": (["sweep", FREE5, "--grid", "mrf.order=1", "--out", "OUT", "--scheduler",
                                          "tcp://127.0.0.1:1", "--connect-timeout", "-1"],
                                         "argument --connect-timeout: must be a positive finite number"),
    "sweep --connect-timeout nan": (["sweep", FREE5, "--grid", "mrf.order=1", "--out", "OUT", "--scheduler",
                                     "tcp://127.0.0.1:1", "--connect-timeout", "nan"],
                                    "argument --connect-timeout: must be a positive finite number"),
    "sweep --out a file": (["sweep", FREE5, "--grid", "mrf.order=1", "--out", "FILE"], "argument --out: .* is a file"),
    "sweep --grid bad": (["sweep", FREE5, "--grid", "order", "--out", "OUT"], "expected KEY=V1,V2"),
    "figs --out a file": (["figs", "--out", "FILE", "--only", "fig2"], "argument --out: .* is a file"),
    "figs --only unknown": (["figs", "--out", "OUT", "--only", "fig99"], "unknown figure"),
    "smooth --speed negative": (["smooth", "WP", "--out", "OUT.csv", "--speed", "-1"], "--speed must be a positive"),
    "smooth --degree negative": (["smooth", "WP", "--out", "OUT.csv", "--degree", "-1"], "--degree -1"),
    "smooth --derivative zero": (["smooth", "WP", "--out", "OUT.csv", "--derivative", "0"], "--derivative must be >= 1"),
    "smooth --altitude nan": (["smooth", "WP", "--out", "OUT.csv", "--altitude", "nan"], "--altitude must be a finite number > 0"),
    "smooth --altitude negative": (["smooth", "WP", "--out", "OUT.csv", "--altitude", "-1"],
                                   r"--altitude must be a finite number > 0 \(as scenario.altitude\), got -1.0"),
    "smooth --durations text": (["smooth", "WP", "--out", "OUT.csv", "--durations", "1,x"], "is not a number"),
    "smooth --qp unknown": (["smooth", "WP", "--out", "OUT.csv", "--qp", "nope"], "error: --qp: unknown QP backend 'nope'"),
    "unknown subcommand": (["fly"], "invalid choice: 'fly'"),
}


def run_cli(argv: list[str]) -> int:
    """``mrfswarm ARGV``'s exit code (argparse exits by SystemExit, the rest by main's return)."""
    try:
        return main(argv)
    except SystemExit as e:
        return e.code


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_flag_value_is_one_line_and_exit_2(case, tmp_path, capsys):
    import re

    argv, pattern = BAD[case]
    (tmp_path / "file").write_text("x")
    (tmp_path / "wp.csv").write_text("x,y\n0,0\n1,0\n2,1\n")
    subs = {"FILE": str(tmp_path / "file"), "OUT": str(tmp_path / "out"), "WP": str(tmp_path / "wp.csv")}
    argv = [re.sub(r"^(FILE|OUT|WP)", lambda m: subs[m.group(1)], a) for a in argv]
    rc = run_cli(argv)
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2, err
    assert len(err) == 1 and err[0].startswith("mrfswarm: error: "), err
    assert re.search(pattern, err[0]), err[0]
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())
    assert not (tmp_path / "out.csv").exists()


def test_negative_seed_from_a_real_process_has_no_traceback(tmp_path):
    p = subprocess.run([sys.executable, "-m", "mrfswarm.cli", "run", FREE5, "--seed", "-5", "--out", str(tmp_path / "o")],
                       capture_output=True, text=True, timeout=120)
    assert p.returncode == 2 and "Traceback" not in p.stderr
    assert p.stderr.strip() == "mrfswarm: error: argument --seed: must be an integer >= 0, got '-5'"


def test_seed_zero_and_large_are_fine(tmp_path):
    for seed in ("0", "123456789"):
        assert main(["run", FREE5, "--seed", seed, "--set", "smoothing.enabled=false", "--out",
                     str(tmp_path / seed)]) == 0


def test_plan_refuses_a_negative_seed():
    import mrfswarm
    from mrfswarm.errors import ConfigError

    with pytest.raises(ConfigError, match="seed = -1: must be an integer >= 0"):
        mrfswarm.plan(FREE5, seed=-1)


def test_a_numpy_integer_seed_is_a_seed(tmp_path):
    """plan() takes any integer as the seed; a NumPy one went into the config as such, and result.json could not be
    written ("Object of type int64 is not JSON serializable"); with a sampled start the scenario refused it under
    a key the user never set."""
    import json

    import numpy as np

    import mrfswarm
    from mrfswarm.outputs import write_outputs

    quick = ["smoothing.enabled=false", "simulation.enabled=false"]
    r = mrfswarm.plan(mrfswarm.load_config(FREE5, overrides=quick), seed=np.int64(3), workers=np.int64(1))
    assert json.loads(json.dumps(r.summary()))["config"]["mrf"]["options"]["seed"] == 3
    write_outputs(r, tmp_path / "out")
    plain = mrfswarm.plan(mrfswarm.load_config(FREE5, overrides=quick), seed=3)
    np.testing.assert_array_equal(r.discrete.paths, plain.discrete.paths)


@pytest.mark.parametrize("workers", [0, -1, 1.5, "2", True])
def test_plan_refuses_bad_workers_before_any_work(workers):
    import mrfswarm
    from mrfswarm.errors import ConfigError

    with pytest.raises(ConfigError, match=r"^workers = .*: must be a whole number >= 1$"):
        mrfswarm.plan(FREE5, workers=workers)


def test_an_equality_only_backend_fails_when_the_config_is_resolved(monkeypatch):
    """The capability record is read at config resolution: no map is loaded, nothing is planned."""
    from mrfswarm import pipeline
    from mrfswarm.config import load_config
    from mrfswarm.errors import ConfigError

    def no_scenario(*args, **kwargs):
        raise AssertionError("the scenario was built before the backend was checked")

    monkeypatch.setattr(pipeline, "build_scenario", no_scenario)
    with pytest.raises(ConfigError, match="smoothing.backend = 'closed_form'"):
        pipeline.plan(CORRIDOR, qp="closed_form")
    # without the continuous stage the backend is not used, so it is not refused
    cfg = load_config(CORRIDOR, ["smoothing.enabled=false"])
    assert pipeline.resolve_config(cfg, qp="closed_form").smoothing.backend == "closed_form"


def test_a_qp_backend_that_is_not_installed_is_said_with_its_key(monkeypatch, missing_qp_backend):
    """As an unknown --nlp names smoothing.nlp, a missing --qp names smoothing.backend (it said "QP backend 'ghost'
    is not installed ..." alone, and a config's backend the same)."""
    import solvers.qp
    from mrfswarm import pipeline
    from solvers.errors import SolverNotFound
    from solvers.registry import Registry

    monkeypatch.setattr(solvers.qp, "BACKENDS", Registry("QP", [*solvers.qp.BACKENDS, missing_qp_backend]))
    with pytest.raises(SolverNotFound, match=r"^smoothing\.backend: QP backend 'ghost' is not installed.*ghost"):
        pipeline.resolve_config(FREE5, qp="ghost")


def test_a_registered_nlp_backend_that_is_not_installed_fails_when_the_config_is_resolved(monkeypatch):
    """With the time refinement on, a missing NLP backend is refused before any map is loaded, naming
    its extra; without it the backend is not used, so it is not refused."""
    import solvers.nlp
    from mrfswarm import config, pipeline
    from mrfswarm.config import load_config
    from solvers.errors import SolverNotFound
    from solvers.nlp import NLPCapabilities
    from solvers.registry import Backend, Registry

    ghost = Backend(name="ghost", entry=lambda *a: None, requires=("no_such_module_xyz",), extra="ghost",
                    capabilities=NLPCapabilities(bounds=True, linear_constraints=False, needs_gradient=True,
                                                 quasi_newton=True, nan_step_back=False, time_limit_native=False))
    registry = Registry("NLP", [*solvers.nlp.BACKENDS, ghost])
    monkeypatch.setattr(solvers.nlp, "BACKENDS", registry)
    monkeypatch.setattr(config, "NLP_BACKENDS", registry)

    def no_scenario(*args, **kwargs):
        raise AssertionError("the scenario was built before the NLP backend was checked")

    monkeypatch.setattr(pipeline, "build_scenario", no_scenario)
    with pytest.raises(SolverNotFound, match=r"^smoothing\.nlp: NLP backend 'ghost' is not installed.*\[ghost\]"):
        pipeline.plan(load_config(FREE5, ["smoothing.time_refinement=true"]), nlp="ghost")
    cfg = load_config(FREE5, ["smoothing.nlp=ghost"])
    assert pipeline.resolve_config(cfg).smoothing.nlp == "ghost"


def test_every_subcommands_help_is_plain_text(capsys):
    """'mrfswarm smooth --help' began "``mrfswarm smooth``: waypoints ..." (its docstring's first line, RST and
    all): neither the command's help nor a subcommand's shows reST markup."""
    from mrfswarm.cli import build_parser

    sub = next(a for a in build_parser()._actions if a.dest == "command")
    assert set(sub.choices) >= {"figs", "run", "smooth", "solvers", "sweep"}
    for argv in [[], *([name] for name in sub.choices)]:
        with pytest.raises(SystemExit):
            main([*argv, "--help"])
        text = capsys.readouterr().out
        assert text.startswith(" ".join(["usage: mrfswarm", *argv]))
        assert not re.search(r"``|:(mod|func|class|meth|attr|data):`", text), (argv, text)
