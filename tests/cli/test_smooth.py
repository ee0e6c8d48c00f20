"""`mrfswarm smooth`: the uav_trajectories job, and one-line errors for every bad input."""

import os
import subprocess
import sys

import numpy as np
import pytest

import solvers.qp
from mrfswarm.cli import main
from mrfswarm.trajectory import (
    MinSnapProblem,
    constant_speed_durations,
    cost_and_gradient,
    integral_squared_derivative,
    max_derivative_norm,
    read_uav_csv,
    scale_to_limits,
    solve_min_snap,
)
from solvers.errors import SolverError
from support.repository import ROOT


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


WALK = "x,y\n0,0\n1,0\n2,1\n2,2\n1,3\n"

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
    "unknown backend": ("x,y\n0,0\n1,1\n", ["--qp", "nope"], "--qp: unknown QP backend 'nope'; installed: "),
    "degree above 7": ("x,y\n0,0\n1,1\n", ["--degree", "9"], "cannot be exported"),
    "degree too low": ("x,y\n0,0\n1,1\n", ["--degree", "5"], "needs degree >= 2q - 1 = 7"),
    "altitude with z": ("x,y,z\n0,0,0\n1,1,1\n", ["--altitude", "2"], "2-D waypoints only"),
    "missing file": (None, [], "cannot read waypoints file"),
    "missing file, time options": (None, ["--refine-time", "--v-max", "2", "--a-max", "4"], "cannot read waypoints file"),
    "v-max zero": ("x,y\n0,0\n1,1\n", ["--v-max", "0"], "--v-max must be a positive finite number (m/s), got 0.0"),
    "v-max negative": ("x,y\n0,0\n1,1\n", ["--v-max", "-1"], "--v-max must be a positive finite number"),
    "v-max nan": ("x,y\n0,0\n1,1\n", ["--v-max", "nan"], "--v-max must be a positive finite number (m/s), got nan"),
    "a-max zero": ("x,y\n0,0\n1,1\n", ["--a-max", "0"], "--a-max must be a positive finite number (m/s^2)"),
    "a-max negative": ("x,y\n0,0\n1,1\n", ["--a-max", "-4"], "--a-max must be a positive finite number"),
    "a-max inf": ("x,y\n0,0\n1,1\n", ["--a-max", "inf"], "--a-max must be a positive finite number (m/s^2), got inf"),
    "limits beyond floating point": ("x,y\n0,0\n1,1\n", ["--v-max", "1e-300"], "beyond floating-point range"),
    "time weight zero": ("x,y\n0,0\n1,1\n", ["--refine-time", "--time-weight", "0"],
                         "--time-weight must be a positive finite number"),
    "time weight negative": ("x,y\n0,0\n1,1\n", ["--refine-time", "--time-weight", "-3"],
                             "--time-weight must be a positive finite number"),
    "time weight nan": ("x,y\n0,0\n1,1\n", ["--refine-time", "--time-weight", "nan"], "--time-weight must be a positive"),
    "time weight without refine": ("x,y\n0,0\n1,1\n", ["--time-weight", "5"], "add --refine-time or drop --time-weight"),
    "retime without limits": ("x,y\n0,0\n1,1\n", ["--retime", "toppra"], "give --v-max and --a-max"),
    "retime without a-max": ("x,y\n0,0\n1,1\n", ["--retime", "toppra", "--v-max", "2"], "give --a-max"),
    "retime without v-max": ("x,y\n0,0\n1,1\n", ["--retime", "toppra", "--a-max", "2"], "give --v-max"),
    "retime with time weight": ("x,y\n0,0\n1,1\n", ["--retime", "toppra", "--v-max", "2", "--a-max", "4", "--refine-time",
                                                   "--time-weight", "3"], "--time-weight has no effect with --retime toppra"),
    "refine with degree above 2q-1": ("x,y\n0,0\n1,1\n", ["--refine-time", "--derivative", "3"],
                                      "--refine-time needs --degree 2q - 1 = 5"),
    "retime with degree above 2q-1": ("x,y\n0,0\n1,1\n", ["--retime", "toppra", "--v-max", "1", "--a-max", "1",
                                                             "--derivative", "3"], "--retime toppra refits with degree 2q - 1 = 5"),
    "refine with repeated waypoint": ("x,y\n0,0\n1,1\n1,1\n", ["--refine-time"], "waypoints 1 and 2 are the same"),
    # the new-user tour's: the closed form wrote a trajectory 1 m off waypoint 2 (exit 0), PIQP 4 mm off at 1e-4 : 1;
    # a speed of 1e308 printed NumPy's overflow warnings, then an error that did not name --speed
    "a microsecond piece": (WALK, ["--durations", "1e-6,1,1,1"], "--durations gives piece 1 a duration of 1e-06 s"),
    "speed too high": (WALK, ["--speed", "1e308"], "--speed 1e+308 gives piece 1 a duration of 1e-308 s"),
    "speed too low": (WALK, ["--speed", "1e-300"], "longer than 100000 s"),
    "speed of a million": (WALK, ["--speed", "1e6"], "shorter than 0.001 s"),
    "durations that lose a waypoint": (WALK, ["--durations", "0.001,1000,0.001,1000"],
                                       "the solved trajectory misses waypoint 3 by"),
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


def test_missing_backend_module_is_one_line(tmp_path, capsys, monkeypatch, missing_qp_backend):
    # a registered backend whose module is not installed: SolverNotFound names the extra
    from solvers.registry import Registry

    fake = Registry("QP", [*solvers.qp.BACKENDS, missing_qp_backend])
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


# ---------------------------------------------------------------- time optimization


def walk_csv(tmp_path, pieces=8, seed=0, name="walk.csv"):
    """A random walk's waypoints, written at full precision; returns (path, waypoints)."""
    rng = np.random.default_rng(seed)
    d = rng.normal(size=(pieces, 2))
    d *= rng.uniform(0.2, 3.0, size=(pieces, 1)) / np.linalg.norm(d, axis=1, keepdims=True)
    W = np.vstack([np.zeros(2), np.cumsum(d, axis=0)])
    return write(tmp_path, "x,y\n" + "".join(f"{x!r},{y!r}\n" for x, y in W.tolist()), name), W


def smooth(tmp_path, wp, *extra, name="out.csv"):
    out = tmp_path / name
    assert main(["smooth", str(wp), "--out", str(out), *extra]) == 0
    return read_uav_csv(out, dim=2)


def peaks(traj):
    return max_derivative_norm(traj, 1)[0], max_derivative_norm(traj, 2)[0]


def dense_peaks(traj, rate=2000):
    t = np.linspace(0.0, traj.duration, int(traj.duration * rate) + 2)
    return np.linalg.norm(traj(t, 1), axis=-1).max(), np.linalg.norm(traj(t, 2), axis=-1).max()


def assert_meets(traj, v_max, a_max, tight=True):
    """Exact maxima within the limits (and a dense sample as an independent check); one tight if asked."""
    v, a = peaks(traj)
    assert v <= v_max * (1 + 1e-9) and a <= a_max * (1 + 1e-9), (v, a)
    vd, ad = dense_peaks(traj)
    assert vd <= v_max * (1 + 1e-9) and ad <= a_max * (1 + 1e-9)
    if tight:
        assert max(v / v_max, a / a_max) == pytest.approx(1.0, rel=1e-9)


def test_limits_alone_slow_down_and_never_speed_up(tmp_path, capsys):
    wp, W = walk_csv(tmp_path)
    T0 = constant_speed_durations(W, 5.0)
    fast = smooth(tmp_path, wp, "--speed", "5", "--v-max", "1", "--a-max", "2", name="fast.csv")
    assert_meets(fast, 1.0, 2.0)
    ratio = fast.durations / T0
    assert ratio.min() > 1 and np.ptp(ratio) < 1e-9 * ratio.max()  # uniformly slower
    assert "for the limits" in capsys.readouterr().out
    slow = smooth(tmp_path, wp, "--speed", "0.1", "--v-max", "1", "--a-max", "2", name="slow.csv")
    np.testing.assert_allclose(slow.durations, constant_speed_durations(W, 0.1), rtol=1e-12)
    assert_meets(slow, 1.0, 2.0, tight=False)


def test_refine_time_alone_keeps_the_total_and_lowers_snap(tmp_path, capsys):
    wp, W = walk_csv(tmp_path, seed=1)
    plain = smooth(tmp_path, wp, "--speed", "1.5", name="plain.csv")
    capsys.readouterr()
    refined = smooth(tmp_path, wp, "--speed", "1.5", "--refine-time", name="refined.csv")
    line = capsys.readouterr().out
    assert "durations refined" in line and "time weight" in line
    assert refined.duration == pytest.approx(plain.duration, rel=1e-9)
    assert not np.allclose(refined.durations, plain.durations, rtol=1e-2)
    assert integral_squared_derivative(refined, 4) < 0.9 * integral_squared_derivative(plain, 4)
    # stationary: dJ/dT_i is the same for every piece (minus the printed weight)
    _, g = cost_and_gradient(MinSnapProblem(W, refined.durations))
    weight = float(line.split("time weight ")[1].split()[0])
    np.testing.assert_allclose(g, -weight, rtol=5e-3)


def objective(traj, weight):
    return integral_squared_derivative(traj, 4) + weight * traj.duration


@pytest.mark.parametrize("v_max,a_max", [(2.0, 4.0), (0.5, 4.0), (3.0, 0.5)], ids=["v2-a4", "v-bound", "a-bound"])
def test_refine_time_with_limits_meets_them_and_lowers_the_objective(tmp_path, v_max, a_max):
    wp, W = walk_csv(tmp_path, seed=2)
    limits = ["--v-max", str(v_max), "--a-max", str(a_max)]
    # from a slow start: without a weight of the user's the refined shares are flown as fast as the limits allow
    refined = smooth(tmp_path, wp, "--speed", "0.1", "--refine-time", *limits, name="refined.csv")
    assert_meets(refined, v_max, a_max)
    plain = smooth(tmp_path, wp, *limits, name="plain.csv")
    # the weight for which the refined output is optimal (Euler: J* = k T / (2q - 1) at a stationary point)
    k = 7 * integral_squared_derivative(refined, 4) / refined.duration
    _, g = cost_and_gradient(MinSnapProblem(W, refined.durations))
    np.testing.assert_allclose(g, -k, rtol=5e-3)
    # its snap + k x time is below the unrefined one's, however that one is scaled (the limits included)
    assert objective(refined, k) <= objective(plain, k)
    base = solve_min_snap(W, constant_speed_durations(W, 1.0)).trajectory
    for alpha in np.geomspace(0.2, 5.0, 41):
        assert objective(refined, k) <= objective(base.time_scaled(alpha), k) * (1 + 1e-9)


def test_refine_time_with_a_weight(tmp_path, capsys):
    wp, W = walk_csv(tmp_path, seed=3)
    free = smooth(tmp_path, wp, "--refine-time", "--time-weight", "50", name="free.csv")
    _, g = cost_and_gradient(MinSnapProblem(W, free.durations))
    np.testing.assert_allclose(g, -50.0, rtol=5e-3)
    v, a = peaks(free)
    # limits the optimum already meets change nothing
    loose = smooth(tmp_path, wp, "--refine-time", "--time-weight", "50", "--v-max", str(2 * v), "--a-max", str(2 * a),
                   name="loose.csv")
    np.testing.assert_allclose(loose.durations, free.durations, rtol=1e-12)
    # limits it exceeds slow it down uniformly, until one is tight
    capsys.readouterr()
    tight = smooth(tmp_path, wp, "--refine-time", "--time-weight", "50", "--v-max", str(v / 2), "--a-max", str(a),
                   name="tight.csv")
    assert_meets(tight, v / 2, a)
    np.testing.assert_allclose(tight.durations / free.durations, tight.duration / free.duration, rtol=1e-9)
    assert tight.duration > free.duration
    weight = float(capsys.readouterr().out.split("time weight ")[1].split()[0])
    alpha = tight.duration / free.duration
    assert weight == pytest.approx(50.0 * alpha**-8, rel=1e-3)


@pytest.mark.parametrize("refine", [False, True], ids=["plain", "refined"])
def test_retime_toppra_meets_the_limits_and_beats_uniform_scaling(tmp_path, capsys, refine):
    wp, W = walk_csv(tmp_path, seed=4)
    flags = ["--v-max", "1.5", "--a-max", "3"] + (["--refine-time"] if refine else [])
    out = smooth(tmp_path, wp, "--retime", "toppra", *flags)
    assert "toppra retimed" in capsys.readouterr().out
    assert_meets(out, 1.5, 3.0)
    assert out.pieces == 10 * (len(W) - 1)
    np.testing.assert_allclose(out(out.knots[::10]), W, atol=1e-9)  # through every waypoint
    for r in (1, 2, 3):
        assert np.abs(out([0.0, out.duration], r)).max() < 1e-9
    durations = constant_speed_durations(W, 1.0)
    if refine:
        from mrfswarm.trajectory import refine_durations

        durations = refine_durations(W, durations).durations
    uniform = scale_to_limits(solve_min_snap(W, durations).trajectory, 1.5, 3.0, allow_speedup=True).trajectory
    assert out.duration < 0.9 * uniform.duration


def test_missing_toppra_is_one_line_naming_the_extra(tmp_path, capsys, monkeypatch):
    import importlib.util

    find_spec = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "toppra" else find_spec(name, *a))
    wp = tmp_path / "not_yet_read.csv"  # checked before any work: before the waypoints are read
    out = tmp_path / "o.csv"
    assert main(["smooth", str(wp), "--out", str(out), "--retime", "toppra", "--v-max", "1", "--a-max", "1"]) == 2
    err = capsys.readouterr().err
    assert err.strip().splitlines() == ['mrfswarm: error: toppra retiming needs toppra, which is not installed: '
                                        'pip install "mrfswarm[toppra]"']
    assert not out.exists()


def test_a_late_failure_writes_nothing(tmp_path, capsys, monkeypatch):
    import mrfswarm.cli.smooth as cmd

    def fail(*args, **kwargs):
        raise SolverError("toppra failed to parametrize the path: test", backend="toppra")

    monkeypatch.setattr(cmd, "retime_toppra", fail)
    wp = write(tmp_path, "x,y\n0,0\n1,1\n2,0\n")
    out = tmp_path / "o.csv"
    assert main(["smooth", str(wp), "--out", str(out), "--refine-time", "--retime", "toppra",
                 "--v-max", "1", "--a-max", "1"]) == 2
    err = capsys.readouterr().err
    assert err.strip().splitlines() == ["mrfswarm: error: toppra failed to parametrize the path: test"]
    assert [p.name for p in tmp_path.iterdir()] == [wp.name]


@pytest.mark.parametrize("extra,match", [(["--v-max", "fast"], "argument --v-max: invalid float value: 'fast'"),
                                         (["--retime", "scale"], "argument --retime: invalid choice: 'scale'")],
                         ids=["v-max text", "unknown retimer"])
def test_unparsable_flags_are_one_line_exit_2(tmp_path, capsys, extra, match):
    wp = write(tmp_path, "x,y\n0,0\n1,1\n")
    with pytest.raises(SystemExit) as e:
        main(["smooth", str(wp), "--out", str(tmp_path / "o.csv"), *extra])
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and match in err
    assert not (tmp_path / "o.csv").exists()


def test_subprocess_time_options(tmp_path):
    wp, W = walk_csv(tmp_path, seed=5)
    out = tmp_path / "t.csv"
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    ok = subprocess.run([sys.executable, "-m", "mrfswarm.cli", "smooth", str(wp), "--out", str(out), "--refine-time",
                         "--v-max", "2", "--a-max", "4"], capture_output=True, text=True, env=env, cwd=tmp_path)
    assert ok.returncode == 0, ok.stderr
    assert "durations refined" in ok.stdout and ok.stderr == ""
    assert_meets(read_uav_csv(out, dim=2), 2.0, 4.0)
    bad = subprocess.run([sys.executable, "-m", "mrfswarm.cli", "smooth", str(wp), "--out", str(tmp_path / "b.csv"),
                          "--retime", "toppra", "--v-max", "2"], capture_output=True, text=True, env=env, cwd=tmp_path)
    assert bad.returncode == 2
    assert bad.stderr.strip().splitlines() == ["mrfswarm: error: --retime toppra retimes to the limits: give --a-max"]
    assert not (tmp_path / "b.csv").exists()


def test_an_existing_out_is_refused_and_kept_unless_overwrite(tmp_path, capsys):
    wp = write(tmp_path, "x,y\n0,0\n1,1\n2,0\n")
    out = tmp_path / "t.csv"
    out.write_text("an earlier trajectory\n")
    assert main(["smooth", str(wp), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "exists" in err and "--overwrite" in err and len(err.strip().splitlines()) == 1
    assert out.read_text() == "an earlier trajectory\n"
    assert main(["smooth", str(wp), "--out", str(out), "--overwrite"]) == 0
    assert read_uav_csv(out, dim=2).pieces == 2


def test_the_waypoints_file_is_never_the_output(tmp_path, capsys):
    """``--out`` the waypoints file with ``--overwrite`` replaced the waypoints by the trajectory (new-user tour)."""
    wp = write(tmp_path, WALK)
    assert main(["smooth", str(wp), "--out", str(wp), "--overwrite"]) == 2
    assert "is the waypoints file" in capsys.readouterr().err
    assert wp.read_text() == WALK


def test_a_byte_order_mark_is_read_as_spreadsheets_write_it(tmp_path, capsys):
    wp = tmp_path / "excel.csv"
    wp.write_bytes("\ufeffx,y\r\n0,0\r\n1,1\r\n".encode())
    out = tmp_path / "o.csv"
    assert main(["smooth", str(wp), "--out", str(out)]) == 0
    assert read_uav_csv(out).pieces == 1


def test_more_pieces_than_a_crazyflie_holds_are_written_with_a_warning(tmp_path, capsys):
    """toppra's refit has 10 pieces per waypoint gap: 40 for 5 waypoints, written without a word before."""
    wp = write(tmp_path, WALK)
    out = smooth(tmp_path, wp, "--retime", "toppra", "--v-max", "1", "--a-max", "1")
    assert out.pieces == 40
    err = capsys.readouterr().err
    assert "mrfswarm: warning: 40 pieces: a Crazyflie's trajectory memory holds 31" in err
