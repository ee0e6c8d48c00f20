"""`mrfswarm smooth`: the uav_trajectories job, and one-line errors for every bad input."""

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import solvers.qp
from mrfswarm.cli import main
from mrfswarm.trajectory import read_uav_csv

ROOT = Path(__file__).resolve().parents[1]


def write(tmp_path, text, name="w.csv"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_happy_path_2d(tmp_path, capsys):
    wp = write(tmp_path, "x,y\n0,0\n3,4\n3,5\n")
    out = tmp_path / "traj.csv"
    rc = main(["smooth", str(wp), "--out", str(out), "--speed", "2", "--altitude", "1.5"])
    assert rc == 0
    line = capsys.readouterr().out.strip()
    assert "2 pieces" in line and "3.000 s" in line and "closed_form" in line and len(line.splitlines()) == 1
    traj = read_uav_csv(out, dim=4)
    np.testing.assert_allclose(traj.durations, [2.5, 0.5])  # |segment| / speed
    np.testing.assert_allclose(traj(traj.knots)[:, :2], [[0, 0], [3, 4], [3, 5]], atol=1e-10)
    np.testing.assert_allclose(traj(traj.knots)[:, 2:], [[1.5, 0.0]] * 3)
    for r in (1, 2, 3):
        assert np.abs(traj([0.0, traj.duration], r)).max() < 1e-9


def test_happy_path_3d_durations_and_every_backend_agree(tmp_path, capsys):
    wp = write(tmp_path, "x, y, z\n0,0,1\n1,0,1.5\n1,1,2\n\n")
    outs = {}
    for name in dict.fromkeys(["closed_form"] + solvers.qp.available()):
        out = tmp_path / f"{name}.csv"
        assert main(["smooth", str(wp), "--out", str(out), "--durations", "1, 2", "--qp", name]) == 0
        outs[name] = read_uav_csv(out)
    ref = outs["closed_form"]
    np.testing.assert_allclose(ref.durations, [1.0, 2.0])
    for name, tr in outs.items():
        np.testing.assert_allclose(tr.coefficients, ref.coefficients, atol=1e-5, err_msg=name)


def test_default_speed_is_one(tmp_path):
    wp = write(tmp_path, "x,y\n0,0\n2,0\n")
    out = tmp_path / "t.csv"
    assert main(["smooth", str(wp), "--out", str(out)]) == 0
    np.testing.assert_allclose(read_uav_csv(out).durations, [2.0])


BAD = {
    "one waypoint": ("x,y\n0,0\n", [], "at least two waypoints"),
    "no waypoints": ("x,y\n", [], "at least two waypoints"),
    "repeated waypoint": ("x,y\n0,0\n1,1\n1,1\n2,0\n", [], "waypoints 1 and 2 are the same"),
    "nan": ("x,y\n0,0\nnan,1\n", [], "finite"),
    "inf": ("x,y\n0,0\n1,inf\n", [], "finite"),
    "bad header": ("a,b\n0,0\n1,1\n", [], "header must be x,y or x,y,z"),
    "ragged row": ("x,y\n0,0\n1,1,2\n", [], "expected 2 values"),
    "not a number": ("x,y\n0,0\n1,one\n", [], "not a number"),
    "empty file": ("", [], "empty file"),
    "zero duration": ("x,y\n0,0\n1,1\n2,0\n", ["--durations", "1,0"], "must be a positive"),
    "negative duration": ("x,y\n0,0\n1,1\n", ["--durations", "-1"], "must be a positive"),
    "nan duration": ("x,y\n0,0\n1,1\n", ["--durations", "nan"], "must be a positive"),
    "text duration": ("x,y\n0,0\n1,1\n", ["--durations", "1,x"], "not a number"),
    "duration count": ("x,y\n0,0\n1,1\n2,0\n", ["--durations", "1,2,3"], "3 values; 3 waypoints need 2"),
    "speed zero": ("x,y\n0,0\n1,1\n", ["--speed", "0"], "--speed"),
    "speed inf": ("x,y\n0,0\n1,1\n", ["--speed", "inf"], "--speed"),
    "speed and durations": ("x,y\n0,0\n1,1\n", ["--speed", "1", "--durations", "1"], "either --durations or --speed"),
    "unknown backend": ("x,y\n0,0\n1,1\n", ["--qp", "nope"], "unknown QP backend 'nope'; installed: "),
    "degree above 7": ("x,y\n0,0\n1,1\n", ["--degree", "9"], "cannot be exported"),
    "degree too low": ("x,y\n0,0\n1,1\n", ["--degree", "5"], "needs degree >= 2q - 1 = 7"),
    "altitude with z": ("x,y,z\n0,0,0\n1,1,1\n", ["--altitude", "2"], "2-D waypoints only"),
    "missing file": (None, [], "cannot read waypoints file"),
}


@pytest.mark.parametrize("case", list(BAD), ids=str)
def test_bad_input_is_one_line_exit_2_and_no_output(tmp_path, capsys, case):
    text, extra, match = BAD[case]
    wp = tmp_path / "missing.csv" if text is None else write(tmp_path, text)
    out = tmp_path / "out.csv"
    rc = main(["smooth", str(wp), "--out", str(out), *extra])
    err = capsys.readouterr().err
    assert rc == 2
    assert len(err.strip().splitlines()) == 1 and err.startswith("mrfswarm: error: ")
    assert match in err, err
    assert "Traceback" not in err
    assert not out.exists()
    assert [p.name for p in tmp_path.iterdir() if p.name != wp.name] == []  # no temp file left either


def test_missing_backend_module_is_one_line(tmp_path, capsys, monkeypatch):
    # a registered backend whose module is not installed: SolverNotFound names the extra
    from solvers.registry import Backend, Registry

    fake = Registry("QP", list(solvers.qp.BACKENDS) + [Backend(name="ghost", entry=None, requires=("no_such_mod_xyz",),
                                                               extra="ghost")])
    monkeypatch.setattr(solvers.qp, "BACKENDS", fake)
    wp = write(tmp_path, "x,y\n0,0\n1,1\n")
    out = tmp_path / "o.csv"
    assert main(["smooth", str(wp), "--out", str(out), "--qp", "ghost"]) == 2
    err = capsys.readouterr().err
    assert "not installed" in err and "mrfswarm[ghost]" in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


def test_out_directory_missing(tmp_path, capsys):
    wp = write(tmp_path, "x,y\n0,0\n1,1\n")
    assert main(["smooth", str(wp), "--out", str(tmp_path / "nope" / "t.csv")]) == 2
    assert "does not exist" in capsys.readouterr().err


def test_subprocess_happy_and_bad(tmp_path):
    wp = write(tmp_path, "x,y\n0,0\n1,0\n1,1\n")
    out = tmp_path / "t.csv"
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    ok = subprocess.run([sys.executable, "-m", "mrfswarm.cli", "smooth", str(wp), "--out", str(out), "--qp", "osqp"],
                        capture_output=True, text=True, env=env, cwd=tmp_path)
    assert ok.returncode == 0, ok.stderr
    assert "2 pieces" in ok.stdout and "backend osqp" in ok.stdout
    assert read_uav_csv(out).pieces == 2
    bad = subprocess.run([sys.executable, "-m", "mrfswarm.cli", "smooth", str(wp), "--out", str(tmp_path / "b.csv"),
                          "--durations", "1"], capture_output=True, text=True, env=env, cwd=tmp_path)
    assert bad.returncode == 2
    assert bad.stderr.strip().splitlines() == ["mrfswarm: error: --durations has 1 value; 3 waypoints need 2"]
    assert not (tmp_path / "b.csv").exists()
