"""crazyswarm2/crazyflies.yaml read as Crazyswarm2 reads it; fly.py against a fake crazyflie_py; cflib_upload.py's
packing with cflib's real classes (only the radio link is fake)."""

import contextlib
import importlib.util
import io
import json
import shutil
import sys
import types

import numpy as np
import pytest
import yaml

from mrfswarm.cli import main
from mrfswarm.trajectory import read_uav_csv
from support.repository import EXPERIMENTS

pytest.importorskip("cflib")


def _run(tmp_path_factory, *sets):
    out = tmp_path_factory.mktemp("run") / "out"
    args = [a for s in ("simulation.enabled=false", *sets) for a in ("--set", s)]
    assert main(["run", str(EXPERIMENTS / "corridor.toml"), "--out", str(out), *args, "--workers", "1"]) == 0
    return out


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    """The corridor by default: 33 steps in 31 pieces, which fit the raw memory."""
    return _run(tmp_path_factory)


@pytest.fixture(scope="module")
def per_step_dir(tmp_path_factory):
    """The corridor with one piece per step (smoothing.max_pieces = 0): 33 pieces, 4356 raw bytes, which do not fit."""
    return _run(tmp_path_factory, "smoothing.max_pieces=0")


def load_script(path, name):
    spec = importlib.util.spec_from_file_location(name, path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_robots_started_one_above_the_other_are_named_in_a_warning_and_the_yaml(tmp_path, caplog):
    from mrfswarm.export.crazyswarm2 import shared_ground, write_crazyswarm2

    stacked = np.array([[2.0, 3.0, 1.5], [2.0, 3.0, 3.5], [2.0, 5.0, 1.5], [2.3, 5.0, 3.0]])
    assert shared_ground(stacked, 0.5) == [(0, 1), (2, 3)]  # the same spot, and 0.3 m apart
    with caplog.at_level("WARNING"):
        write_crazyswarm2(stacked, tmp_path / "a", radius=0.25)
    text = (tmp_path / "a" / "crazyswarm2" / "crazyflies.yaml").read_text()
    assert "cf1 and cf2, cf3 and cf4" in caplog.text and "# WARNING: robots start above the same ground spot" in text
    assert len(yaml.safe_load(text)["robots"]) == 4  # still the file Crazyswarm2 reads
    caplog.clear()
    # thirty stacked pairs (a sampled 3-D start of 100 robots): six named, the rest counted, not a 650-character line
    tower = np.array([[x, 0.0, z] for x in range(30) for z in (1.0, 3.0)])
    with caplog.at_level("WARNING"):
        write_crazyswarm2(tower, tmp_path / "t", radius=0.25)
    assert "cf11 and cf12 and 24 more pairs)" in caplog.text and "cf13" not in caplog.text
    caplog.clear()
    apart = stacked + np.array([[0.0, 0, 0], [0.5, 0, 0], [0, 0, 0], [0.5, 0, 0]])
    assert shared_ground(apart, 0.5) == []
    with caplog.at_level("WARNING"):
        write_crazyswarm2(apart, tmp_path / "b", radius=0.25)
    assert not caplog.text and "WARNING" not in (tmp_path / "b" / "crazyswarm2" / "crazyflies.yaml").read_text()


def test_robots_that_end_one_above_the_other_are_named_in_a_warning_and_the_yaml(tmp_path, caplog):
    """The scripts land every robot straight down at once: two that end above the same ground spot land one onto
    the other (a 3-D goal with robots stacked in it); only the starts were checked."""
    from mrfswarm.export.crazyswarm2 import write_crazyswarm2

    starts = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [2.0, 0.0, 1.0]])
    ends = np.array([[12.0, 4.0, 4.5], [9.0, 4.0, 1.0], [12.0, 4.0, 0.5]])
    with caplog.at_level("WARNING"):
        write_crazyswarm2(starts, tmp_path / "a", radius=0.25, ends=ends)
    text = (tmp_path / "a" / "crazyswarm2" / "crazyflies.yaml").read_text()
    assert "robots end above the same ground spot (cf1 and cf3)" in caplog.text
    assert "# WARNING: robots end above the same ground spot" in text and "start above" not in text
    caplog.clear()
    with caplog.at_level("WARNING"):
        write_crazyswarm2(starts, tmp_path / "b", radius=0.25, ends=ends + [[0.5, 0, 0], [0, 0, 0], [0, 0, 0]])
    assert not caplog.text


@pytest.mark.parametrize("distance, v_max, a_max, j_max", [(4.5, 2.0, 4.0, 4.0), (0.9, 1.0, 2.0, 4.0),
                                                           (40.0, 0.5, 0.5, 0.5), (5.0, 10.0, 0.2, 100.0),
                                                           (5.0, 10.0, 10.0, 0.05)])
def test_the_maneuvers_keep_the_firmwares_polynomial_within_the_plans_limits(distance, v_max, a_max, j_max):
    """Take-off, go-to and landing fly the firmware's 7th-order rest-to-rest polynomial: over its duration it stays
    within the limits, each of which binds where the duration is longer than the 3 s floor. At the scripts' former 3 s,
    a take-off to 4.5 m peaked at 3.3 m/s against a v_max of 2."""
    from mrfswarm.export.crazyswarm2 import MANEUVER_MIN_S, REST_TO_REST, maneuver_duration

    T = maneuver_duration(distance, v_max, a_max, j_max)
    tau = np.linspace(0.0, 1.0, 200001)
    peaks = [np.abs(REST_TO_REST.deriv(k)(tau)).max() * distance / T**k for k in (1, 2, 3)]
    ratios = np.array(peaks) / [v_max, a_max, j_max]
    assert ratios.max() <= 1 + 1e-9
    assert T == MANEUVER_MIN_S or ratios.max() > 1 - 1e-6  # longer than the floor only as long as a limit asks
    assert maneuver_duration(4.5, 2.0, 4.0, 4.0) > 4.9  # 35/16 x 4.5 / 2
    assert np.abs(REST_TO_REST.deriv(1)(tau)).max() * 4.5 / MANEUVER_MIN_S > 3.2


def test_the_scripts_fly_the_maneuvers_of_the_run(run_dir, tmp_path, monkeypatch):
    """maneuvers.yaml: the corridor's take-off to 1 m and landing within its limits take the 3 s floor; fly.py and
    cflib_upload.py fly what the file says (a taller plan's longer durations)."""
    m = yaml.safe_load((run_dir / "crazyswarm2" / "maneuvers.yaml").read_text())
    assert m["takeoff_s"] == m["goto_s"] == m["land_s"] == 3.0 and m["land_height_m"] == 0.04
    assert m["limits"] == {"v_max": 2.0, "a_max": 4.0, "j_max": 4.0}
    plan = tmp_path / "plan"
    shutil.copytree(run_dir, plan)
    tall = {**m, "takeoff_s": 4.92, "goto_s": 3.5, "land_s": 5.1, "land_height_m": 0.05}
    (plan / "crazyswarm2" / "maneuvers.yaml").write_text(yaml.safe_dump(tall))
    calls = []
    monkeypatch.setattr(sys, "modules", {**sys.modules, **fake_crazyflie_py(calls, ["cf1", "cf2", "cf3", "cf4", "cf5"])})
    load_script(plan / "crazyswarm2" / "fly.py", "fly_tall").main([])
    assert next(c for c in calls if c[0] == "takeoff")[2] == 4.92
    assert {c[4] for c in calls if c[0] == "goTo"} == {3.5}
    assert next(c for c in calls if c[0] == "land")[1:] == (0.05, 5.1)
    seq = [c[0] for c in calls]
    assert calls[seq.index("takeoff") + 1] == ("sleep", 4.92 + 1.0)
    cflib_upload = load_script(plan / "crazyflie" / "cflib_upload.py", "cflib_upload_tall")
    assert cflib_upload.maneuvers(plan) == tall
    (plan / "crazyswarm2" / "maneuvers.yaml").unlink()  # a folder written before the file: 3 s each
    assert cflib_upload.maneuvers(plan)["takeoff_s"] == 3.0


def test_robots_that_fly_into_the_ground_of_the_export_are_named_in_a_warning_and_the_yaml(tmp_path, caplog):
    """A 3-D plan whose map keeps its floor below z = 0 (the default origin): its robots' lowest points are found
    on the curves, between knots too, and those nearer than the radius to z = 0 named, lowest first."""
    from mrfswarm.export.crazyswarm2 import below_ground, lowest_points, write_crazyswarm2
    from mrfswarm.trajectory import PiecewisePolynomial

    # z(t) = 1 - 4 t (1 - t) on [0, 1]: lowest 0 at t = 0.5, inside the piece; then a second, flat piece
    def dip(depth, z0=1.0):
        c = np.zeros((2, 3, 3))  # (pieces, coefficients in t, axes)
        c[0, :, 0], c[1, 0, 0] = [0.0, 1.0, 0.0], 1.0
        c[0, :, 2] = [z0, -4 * (z0 - depth), 4 * (z0 - depth)]
        c[1, 0, 2] = z0
        return PiecewisePolynomial(np.array([1.0, 1.0]), c)

    trs = [dip(0.5), dip(-0.2), dip(0.1), dip(1.0)]
    np.testing.assert_allclose(lowest_points(trs), [0.5, -0.2, 0.1, 1.0], atol=1e-12)
    lowest = lowest_points(trs)
    assert below_ground(lowest, 0.25).tolist() == [1, 2]
    starts = np.array([[0.0, y, 1.0] for y in range(4)])
    with caplog.at_level("WARNING"):
        write_crazyswarm2(starts, tmp_path / "a", radius=0.25, lowest=lowest)
    text = (tmp_path / "a" / "crazyswarm2" / "crazyflies.yaml").read_text()
    assert "2 robots fly nearer than the robot radius (0.25 m)" in caplog.text
    assert "(cf2 down to z = -0.2 m, cf3 down to z = 0.1 m)" in caplog.text and "# WARNING: 2 robots fly" in text
    caplog.clear()
    with caplog.at_level("WARNING"):  # a robot flying on the ground itself: no float noise in the message
        write_crazyswarm2(starts[:1], tmp_path / "c", radius=0.25, lowest=np.array([-6.98e-23]))
    assert "(cf1 down to z = 0 m)" in caplog.text
    caplog.clear()
    with caplog.at_level("WARNING"):
        write_crazyswarm2(starts, tmp_path / "b", radius=0.25, lowest=lowest_points([dip(0.5), dip(0.3)]))
    assert not caplog.text and "WARNING" not in (tmp_path / "b" / "crazyswarm2" / "crazyflies.yaml").read_text()


@pytest.mark.parametrize("altitude, warned", [(0.05, True), (0.1, False), (1.0, False)])
def test_a_2d_plan_flown_below_its_radius_is_a_warning(tmp_path, caplog, altitude, warned):
    """scenario.altitude 0.05 with radius 0.1 took off to 5 cm without a word (a 3-D tour)."""
    from mrfswarm.export.crazyswarm2 import write_crazyswarm2

    starts = np.array([[0.0, 0.0], [1.0, 0.0]])
    with caplog.at_level("WARNING"):
        write_crazyswarm2(starts, tmp_path / "a", radius=0.1, altitude=altitude)
    text = (tmp_path / "a" / "crazyswarm2" / "crazyflies.yaml").read_text()
    said = "flies at scenario.altitude = 0.05 m, nearer than the robot radius (0.1 m)"
    assert (said in caplog.text) == warned and (said in text) == warned


def test_robots_whose_takeoff_or_landing_column_holds_an_obstacle_are_named():
    """A shelf (voxels x, y in [0, 1.5) m, z in [1.5, 2) m, 0.5 m voxels, the floor at z = 0) over one robot's
    ground spot: the scripts fly every robot straight up to the highest start (2.25 m), and it would climb
    through the shelf (new-user tour: written without a word). A robot 0.25 m beside the shelf's edge, farther
    than its radius 0.2 m, is not named; one 0.15 m beside it is; a column below the shelf is not blocked."""
    from mrfswarm.export.crazyswarm2 import blocked_columns

    occ = np.zeros((8, 6, 5), dtype=bool)
    occ[0:3, 0:3, 3] = True
    origin, res = np.array([0.25, 0.25, 0.25]), 0.5
    xy = np.array([[0.75, 0.75], [1.75, 0.75], [1.65, 0.75], [2.75, 2.25]])
    assert blocked_columns(occ, origin, res, xy, np.full(4, 2.25), 0.2).tolist() == [0, 2]
    assert blocked_columns(occ, origin, res, xy, np.full(4, 1.0), 0.2).tolist() == []  # under the shelf only
    assert blocked_columns(occ, origin, res, xy, np.full(4, 1.35), 0.2).tolist() == [0, 2]  # radius from its floor


def test_a_blocked_takeoff_is_a_warning_of_the_run(tmp_path, caplog):
    toml = tmp_path / "shelf.toml"
    toml.write_text("""
[scenario]
map = { kind = "boxes", size = [8, 6, 5], resolution = 0.5, origin = [0.25, 0.25, 0.25], boxes = [
    { center = [0.75, 0.75, 1.75], size = [1.5, 1.5, 0.5] } ] }
start = { positions = [[0.75, 0.75, 0.75], [1.75, 0.75, 0.75], [0.75, 1.75, 0.25], [2.75, 2.25, 2.25]] }
goal = [3.75, 2.75, 1.25]
robot_radius = 0.2
[simulation]
enabled = false
""")
    with caplog.at_level("WARNING"):
        assert main(["run", str(toml), "--out", str(tmp_path / "run")]) == 0
    assert "cf1 would take off straight up through an obstacle over its ground spot" in caplog.text
    assert "# WARNING: cf1 would take off" in (tmp_path / "run" / "crazyswarm2" / "crazyflies.yaml").read_text()


def test_yaml_as_crazyswarm2_launch_reads_it(run_dir):
    c = yaml.safe_load((run_dir / "crazyswarm2" / "crazyflies.yaml").read_text())
    fileversion = c.get("fileversion", 1)
    assert fileversion == 3
    rigid = {}
    for key, value in c["robots"].items():  # crazyflie/launch/launch.py's loop
        kind = c["robot_types"][value["type"]]
        if value["enabled"] and kind["motion_capture"]["tracking"] == "librigidbodytracker":
            rigid[key] = {"initial_position": value["initial_position"], "marker": kind["motion_capture"]["marker"],
                          "dynamics": kind["motion_capture"]["dynamics"]}
    assert list(rigid) == ["cf1", "cf2", "cf3", "cf4", "cf5"]
    assert [v["initial_position"] for v in rigid.values()] == [[4.0, y, 0.0] for y in (16.0, 18.0, 20.0, 22.0, 24.0)]
    ids = [int(v["uri"][-2:], 16) for v in c["robots"].values()]  # crazyflie_py's cfid
    assert ids == [1, 2, 3, 4, 5] and c["robots"]["cf1"]["uri"] == "radio://0/80/2M/E7E7E7E701"
    assert c["all"]["firmware_params"]["commander"]["enHighLevel"] == 1
    # crazyflie_server (C++) counts a type as tracked by motion capture when it says so, as upstream's file does
    assert all(c["robot_types"][v["type"]]["motion_capture"]["enabled"] is True for v in c["robots"].values())


class FakeTrajectory:
    """crazyflie_py.uav_trajectory.Trajectory: loadcsv as Crazyswarm2 does it (IMRCLab/crazyswarm2 f6154e2,
    crazyflie_py/uav_trajectory.py: np.loadtxt without ndmin, so one row is a 1-D array)."""

    def loadcsv(self, filename):
        data = np.loadtxt(filename, delimiter=",", skiprows=1, usecols=range(33))
        P = types.SimpleNamespace
        self.polynomials = [P(duration=r[0], px=P(p=r[1:9]), py=P(p=r[9:17]), pz=P(p=r[17:25]), pyaw=P(p=r[25:33]))
                            for r in data]
        self.duration = float(np.sum(data[:, 0]))
        self.rows = data

    def n_pieces(self):
        return len(self.polynomials)


def fake_crazyflie_py(calls, names):
    class Cf:
        def __init__(self, name):
            self.name = name

        def uploadTrajectory(self, trajectory_id, offset, trajectory):
            calls.append(("upload", self.name, trajectory_id, offset, trajectory))

        def goTo(self, goal, yaw, duration, relative=False, groupMask=0):
            calls.append(("goTo", self.name, np.asarray(goal, dtype=float), yaw, duration, relative))

    class Server:
        def __init__(self):
            self.crazyfliesByName = {n: Cf(n) for n in names}
            self.crazyflies = list(self.crazyfliesByName.values())

        def takeoff(self, targetHeight, duration, groupMask=0):
            calls.append(("takeoff", targetHeight, duration))

        def startTrajectory(self, trajectoryId, timescale=1.0, reverse=False, relative=True, groupMask=0):
            calls.append(("start", trajectoryId, timescale, reverse, relative))

        def land(self, targetHeight, duration, groupMask=0):
            calls.append(("land", targetHeight, duration))

    class TimeHelper:
        def sleep(self, duration):
            calls.append(("sleep", duration))

    class Crazyswarm:
        def __init__(self):
            calls.append(("connect",))  # the radio links: nothing may be refused after this but a server mismatch
            self.allcfs = Server()
            self.timeHelper = TimeHelper()

    pkg = types.ModuleType("crazyflie_py")
    pkg.Crazyswarm = Crazyswarm
    sub = types.ModuleType("crazyflie_py.uav_trajectory")
    sub.Trajectory = FakeTrajectory
    pkg.uav_trajectory = sub
    return {"crazyflie_py": pkg, "crazyflie_py.uav_trajectory": sub}


def test_fly_py_refuses_a_flight_that_does_not_fit(per_step_dir, monkeypatch):
    # 33 pieces do not fit raw: fly.py refuses before any call, the radio link included
    calls = []
    monkeypatch.setattr(sys, "modules", {**sys.modules, **fake_crazyflie_py(calls, ["cf1", "cf2", "cf3", "cf4", "cf5"])})
    fly = load_script(per_step_dir / "crazyswarm2" / "fly.py", "fly_per_step")
    with pytest.raises(SystemExit, match="33 pieces.*31 raw pieces.*--compressed"):
        fly.main([])
    assert calls == []


def test_fly_py_refuses_a_flight_that_does_not_fit_without_crazyswarm2_too(per_step_dir, monkeypatch):
    """The pieces are counted before crazyflie_py is imported: on a machine without the ROS workspace the refusal
    names the pieces, not the missing package (the docs say fly.py refuses such a plan before any link)."""
    monkeypatch.setitem(sys.modules, "crazyflie_py", None)  # import crazyflie_py raises ImportError
    fly = load_script(per_step_dir / "crazyswarm2" / "fly.py", "fly_per_step_no_ros")
    with pytest.raises(SystemExit, match="33 pieces.*31 raw pieces.*--compressed"):
        fly.main([])


def test_fly_py_without_crazyswarm2_is_one_line_saying_what_provides_it(run_dir, monkeypatch, capsys):
    fly = load_script(run_dir / "crazyswarm2" / "fly.py", "fly_missing")
    monkeypatch.setitem(sys.modules, "crazyflie_py", None)  # import crazyflie_py raises ImportError
    with pytest.raises(SystemExit) as e:
        fly.main([])
    msg = str(e.value.code)
    assert msg.startswith("fly.py: Crazyswarm2's Python package crazyflie_py is not importable") and "\n" not in msg
    assert "source install/setup.bash" in msg


def test_cflib_upload_without_cflib_is_one_line_saying_what_to_install(run_dir, monkeypatch):
    script = load_script(run_dir / "crazyflie" / "cflib_upload.py", "cflib_upload_missing")
    for name in [m for m in sys.modules if m == "cflib" or m.startswith("cflib.")]:
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, "cflib", None)
    with pytest.raises(SystemExit) as e:
        script.run(["--robots", "0"])
    msg = str(e.value.code)
    assert msg.startswith("cflib_upload.py: ") and "cflib" in msg and "pip install" in msg and "\n" not in msg, msg


def test_cflib_upload_without_a_radio_is_one_line_saying_which_links(run_dir, monkeypatch, capsys):
    """Without a Crazyradio (or a robot answering), cflib logs a traceback per link and its swarm raises from a
    thread: about 200 lines. The upload says in one line which links did not open, and why, through cflib itself
    (no radio here; a Crazyradio plugged in would be found)."""
    pytest.importorskip("cflib")
    from cflib.drivers import crazyradio

    if crazyradio._find_devices():
        pytest.skip("a Crazyradio is plugged in")
    script = load_script(run_dir / "crazyflie" / "cflib_upload.py", "cflib_upload_radio")
    monkeypatch.chdir(run_dir / "crazyflie")
    with pytest.raises(SystemExit) as e:
        script.run(["--robots", "0,1", "--compressed", "--fly"])
    msg = str(e.value.code)
    assert msg.startswith("cflib_upload.py: cannot open the links to radio://") and "\n" not in msg, msg
    assert "Crazyradio" in msg and msg.count("radio://") == 2
    assert "Traceback" not in capsys.readouterr().err


def test_fly_py_help_flies_nothing(run_dir, monkeypatch, capsys):
    calls = []
    monkeypatch.setattr(sys, "modules", {**sys.modules, **fake_crazyflie_py(calls, ["cf1", "cf2", "cf3", "cf4", "cf5"])})
    fly = load_script(run_dir / "crazyswarm2" / "fly.py", "fly_help")
    with pytest.raises(SystemExit) as e:
        fly.main(["--help"])
    assert e.value.code == 0 and "Crazyswarm2" in capsys.readouterr().out and calls == []
    with pytest.raises(SystemExit):
        fly.main(["--fly-now"])  # an unknown argument: refused, nothing flown
    assert calls == []


def test_fly_py_refuses_a_server_with_other_robots(run_dir, monkeypatch):
    # the server launched with another yaml (a robot more): takeoff would command a robot without a trajectory
    calls = []
    names = ["cf1", "cf2", "cf3", "cf4", "cf5", "cf6"]
    monkeypatch.setattr(sys, "modules", {**sys.modules, **fake_crazyflie_py(calls, names)})
    fly = load_script(run_dir / "crazyswarm2" / "fly.py", "fly_other_server")
    with pytest.raises(SystemExit, match=r"server flies \['cf1', .*'cf6'\], this plan \['cf1', .*'cf5'\]"):
        fly.main([])
    assert calls == [("connect",)]


def test_fly_py_calls_in_order_with_each_robots_csv(run_dir, monkeypatch):
    # the corridor's 31 pieces (some spanning two steps) fit: the whole plan is flown
    calls = []
    names = ["cf1", "cf2", "cf3", "cf4", "cf5"]
    monkeypatch.setattr(sys, "modules", {**sys.modules, **fake_crazyflie_py(calls, names)})
    load_script(run_dir / "crazyswarm2" / "fly.py", "fly_corridor").main([])
    kinds = [c[0] for c in calls if c[0] != "sleep"]
    assert kinds == ["connect"] + ["upload"] * 5 + ["takeoff"] + ["goTo"] * 5 + ["start", "land"]
    seq = [c[0] for c in calls]
    for a, b in (("takeoff", "goTo"), ("goTo", "start"), ("start", "land")):  # a wait between phases
        assert seq[seq.index(b) - 1] == "sleep" and seq.index(a) < seq.index(b)
    takeoff = next(c for c in calls if c[0] == "takeoff")
    assert takeoff[1] == 1.0  # the plan's altitude
    start = next(c for c in calls if c[0] == "start")
    assert start[4] is False  # absolute positions
    waits = [c[1] for c in calls if c[0] == "sleep"]
    uploads = {c[1]: c[4] for c in calls if c[0] == "upload"}
    for name in names:
        i = int(name[2:]) - 1
        csv = read_uav_csv(run_dir / "trajectories" / f"robot_{i}.csv", dim=4)
        up = uploads[name]
        assert csv.pieces == 31 and np.array_equal(up.rows[:, 0], csv.durations)
        assert np.array_equal(up.rows[:, 1:].reshape(-1, 4, 8), np.moveaxis(csv.coefficients, 1, 2))
        goal = next(c[2] for c in calls if c[0] == "goTo" and c[1] == name)
        assert np.allclose(goal, [*csv.evaluate(0.0)[:2], 1.0])
    assert waits[seq[:seq.index("land")].count("sleep") - 1] >= max(u.duration for u in uploads.values())


class FakeLink:
    """Only the radio: cflib's Memory handler replaced by one that records the bytes and acknowledges."""

    def __init__(self):
        self.data = None

    def write(self, memory, addr, data, flush_queue=False):
        self.data = bytes(data)
        memory.write_done(memory, addr)
        return True


@pytest.mark.parametrize("compressed", [False, True], ids=["raw", "compressed"])
def test_cflib_upload_packs_with_cflib(run_dir, compressed):
    from cflib.crazyflie.high_level_commander import HighLevelCommander
    from cflib.crazyflie.mem import MemoryElement, TrajectoryMemory

    from mrfswarm.export import cflib_

    script = load_script(run_dir / "crazyflie" / "cflib_upload.py", f"cflib_upload_{compressed}")
    assert script.uris(run_dir) == {i: f"radio://0/80/2M/E7E7E7E70{i + 1}" for i in range(5)}
    elements, origin = script.pieces([0, 3], compressed, run_dir)
    packets = []
    link = FakeLink()
    memory = TrajectoryMemory(id=1, type=MemoryElement.TYPE_TRAJ, size=4096, mem_handler=link)
    cf = types.SimpleNamespace(mem=types.SimpleNamespace(get_mems=lambda kind: [memory]),
                               send_packet=packets.append, link_uri="radio://fake")
    cf.high_level_commander = HighLevelCommander(cf)
    n = script.upload(cf, elements[3], compressed)
    assert n == len(link.data) == (31 * 132 if not compressed else 8 + 31 * 31 + 3)
    csv = read_uav_csv(run_dir / "trajectories" / "robot_3.csv", dim=2)
    if compressed:
        dec = cflib_.decode_compressed(link.data, origin, dim=2)
        t = np.linspace(0, dec.duration, 2001)
        assert np.abs(dec.evaluate(t) - csv.evaluate(t)).max() < 3e-3
        assert link.data == cflib_.pack_compressed(script.compressed_plan(run_dir), 3)  # the certified bytes
    else:
        dec = cflib_.decode_raw(link.data, dim=2)
        assert dec.pieces == csv.pieces == 31
        assert np.allclose(dec.coefficients, csv.coefficients, rtol=1e-6, atol=1e-6)
    define = packets[-1].data
    kind = HighLevelCommander.TRAJECTORY_TYPE_POLY4D_COMPRESSED if compressed else HighLevelCommander.TRAJECTORY_TYPE_POLY4D
    assert define[0] == HighLevelCommander.COMMAND_DEFINE_TRAJECTORY and define[1] == script.TRAJECTORY_ID
    assert define[3] == kind and define[-1] == 31


def test_cflib_upload_refuses_a_compressed_flight_that_is_not_certified(run_dir, tmp_path):
    script = load_script(run_dir / "crazyflie" / "cflib_upload.py", "cflib_upload_uncertified")
    assert script.not_certified(run_dir) == []  # the corridor's compressed flight certifies
    plan = tmp_path / "plan"
    shutil.copytree(run_dir, plan)
    res = json.loads((plan / "result.json").read_text())
    res["crazyflie"]["compressed"]["not_certified_robots"] = [3]
    (plan / "result.json").write_text(json.dumps(res))
    with pytest.raises(SystemExit, match=r"compressed flight of robots \[3\] is not certified.*without --compressed"):
        script.pieces([0, 3], True, plan)
    assert set(script.pieces([0, 1], True, plan)[0]) == {0, 1}  # the certified ones still go
    assert set(script.pieces([3], False, plan)[0]) == {3}  # and robot 3's raw pieces
    # a plan without a compressed flight (too wide for it): its reason, not "not certified"
    res["crazyflie"]["compressed"] = {"error": "the flight spans 84.000 m, more than the format's 65.535 m"}
    (plan / "result.json").write_text(json.dumps(res))
    with pytest.raises(SystemExit, match=r"no compressed flight: the flight spans 84.000 m.*without --compressed"):
        script.pieces([0], True, plan)


def test_cflib_upload_refuses_raw_pieces_that_do_not_fit(per_step_dir):
    from cflib.crazyflie.mem import MemoryElement, TrajectoryMemory

    script = load_script(per_step_dir / "crazyflie" / "cflib_upload.py", "cflib_upload_per_step")
    elements, _ = script.pieces([3], False, per_step_dir)
    link = FakeLink()
    memory = TrajectoryMemory(id=1, type=MemoryElement.TYPE_TRAJ, size=4096, mem_handler=link)
    cf = types.SimpleNamespace(mem=types.SimpleNamespace(get_mems=lambda kind: [memory]),
                               send_packet=lambda p: None, link_uri="radio://fake")
    with pytest.raises(script.UploadError, match="4356 bytes do not fit.*--compressed"):
        script.upload(cf, elements[3], False)
    assert link.data is None  # nothing written


def fake_swarm(script, monkeypatch, calls, write_ok=True):
    """cflib's own ``Swarm`` (its threads, its ``parallel_safe``) over fake links: each robot's memory and
    high-level commander record what they are asked."""
    from cflib.crazyflie.swarm import Swarm

    class Memory:
        size = 4096

        def __init__(self, uri):
            self.uri, self.trajectory = uri, []

        def write_data_sync(self):
            calls.append(("write", self.uri))
            return write_ok

    class Commander:
        def __init__(self, uri):
            self.uri = uri

        def __getattr__(self, name):
            return lambda *a, **k: calls.append((name, self.uri))

    class Factory:
        def construct(self, uri):
            memory = Memory(uri)
            cf = types.SimpleNamespace(link_uri=uri, mem=types.SimpleNamespace(get_mems=lambda kind: [memory]),
                                       high_level_commander=Commander(uri))
            return types.SimpleNamespace(cf=cf, open_link=lambda: None, close_link=lambda: None)

    def open_swarm(uris, factory):
        calls.append(("open",))
        swarm = Swarm(uris, factory=Factory())
        swarm.reset_estimators = lambda: calls.append(("reset",))  # reads the robots' logs
        return swarm

    monkeypatch.setattr(script, "open_swarm", open_swarm)
    monkeypatch.setattr(script.time, "sleep", lambda s: None)


def test_cflib_upload_a_failed_upload_stops_the_script_before_the_flight(run_dir, monkeypatch):
    """cflib's swarm uploads in threads, where the refusal (a ``SystemExit``) ended its thread without a word: the
    script took off and started the trajectory, which a robot flies from whatever an earlier upload left."""
    script = load_script(run_dir / "crazyflie" / "cflib_upload.py", "cflib_upload_failed_write")
    calls = []
    fake_swarm(script, monkeypatch, calls, write_ok=False)
    with pytest.raises(SystemExit) as e:
        script.run(["--robots", "0,1", "--fly"])
    msg = str(e.value.code)
    assert msg.startswith("cflib_upload.py: the upload failed: uploading to radio://") and "\n" not in msg, msg
    assert [c[0] for c in calls] == ["open", "write", "write"]  # no take-off, no start
    calls.clear()
    fake_swarm(script, monkeypatch, calls)  # the same plan uploaded: flown
    assert script.run(["--robots", "0,1", "--fly"]) == 0
    assert [c[0] for c in calls if c[0] not in ("write", "define_trajectory")][:4] == ["open", "reset", "takeoff",
                                                                                        "takeoff"]


def test_cflib_upload_refuses_raw_pieces_that_do_not_fit_before_any_link(per_step_dir, monkeypatch):
    """33 raw pieces: refused before the radio (with one, the refusal came after the links opened), saying that
    their compressed pieces, which fit and are certified, fly them."""
    script = load_script(per_step_dir / "crazyflie" / "cflib_upload.py", "cflib_upload_per_step_early")
    calls = []
    fake_swarm(script, monkeypatch, calls)
    with pytest.raises(SystemExit, match=r"robots \[0, 1\] take up to 4356 bytes.*upload them compressed"):
        script.run(["--robots", "0,1"])
    assert calls == []
    assert script.run(["--robots", "0,1", "--compressed"]) == 0 and calls[0] == ("open",)


@pytest.fixture(scope="module")
def too_long_dir(tmp_path_factory):
    """Two robots crossing 72 m, one piece per step: 72 raw pieces, and wider than the compressed format."""
    config = tmp_path_factory.mktemp("long") / "long.toml"
    config.write_text('[scenario]\nmap = { kind = "free", size = [80, 6] }\n'
                      'start = { positions = [[2, 2], [2, 4]] }\ngoal = [77, 3]\n')
    out = config.parent / "out"
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        assert main(["run", str(config), "--out", str(out), "--set", "simulation.enabled=false",
                     "--set", "smoothing.max_pieces=0", "--workers", "1"]) == 0
    return out, err.getvalue()


def test_a_flight_no_format_holds_is_said_per_robot_with_what_to_plan(too_long_dir, monkeypatch):
    """Neither raw (72 pieces) nor compressed (72 m wide) holds it: fly.py sent the user to --compressed, which
    sent them to the raw pieces, which (at the radio) sent them to --compressed. The run, both scripts and
    result.json say that no format flies these robots, and what to plan instead."""
    too_long_dir, stderr = too_long_dir
    section = json.loads((too_long_dir / "result.json").read_text())["crazyflie"]
    assert [r["flies"] for r in section["robots"]] == [None, None]
    advice = section["advice"]
    assert "robots 0, 1 (2 of 2) fit no Crazyflie trajectory memory" in advice and "72 pieces" in advice
    assert "spans 72.000 m" in advice and "smoothing.max_pieces = 31" in advice
    assert "use the raw format" not in advice  # the compressed format's own advice, wrong here
    assert f"mrfswarm: warning: {advice}" in stderr
    fly = load_script(too_long_dir / "crazyswarm2" / "fly.py", "fly_too_long")
    with pytest.raises(SystemExit) as e:
        fly.main([])
    assert str(e.value.code) == f"fly.py: cf1's trajectory has 72 pieces; a Crazyflie holds 31 raw pieces: {advice}"
    script = load_script(too_long_dir / "crazyflie" / "cflib_upload.py", "cflib_upload_too_long")
    calls = []
    fake_swarm(script, monkeypatch, calls)
    with pytest.raises(SystemExit) as e:
        script.run([])
    assert str(e.value.code) == f"cflib_upload.py: {advice}" and calls == []
    with pytest.raises(SystemExit, match="no compressed flight: the flight spans 72.000 m"):
        script.run(["--compressed"])


def test_the_advice_names_what_fails_and_what_to_plan():
    from mrfswarm.export.crazyflie_memory import advice

    robot = {"robot": 0, "pieces": 160, "bytes_raw": 21120, "fits_raw": False, "bytes_compressed": 4971,
             "fits_compressed": False, "compressed_certified": True, "flies": None}
    fits = {**robot, "robot": 1, "pieces": 31, "bytes_raw": 4092, "fits_raw": True, "flies": "raw"}
    section = {"robots": [robot, fits], "compressed": {"not_certified_robots": []}}
    text = advice(section, 31)
    assert text.startswith("robot 0 fits no Crazyflie trajectory memory (4096 bytes): raw 160 pieces, 21120 bytes")
    assert "compressed up to 4971 bytes" in text and "cflib_upload.py refuse it:" in text  # one robot: "it"
    assert "plan a shorter flight" in text and "max_pieces" not in text  # the piece limit was on: too long a flight
    assert "smoothing.max_pieces = 31" in advice(section, 0)
    assert advice({"robots": [fits], "compressed": {}}, 31) is None
    uncertified = {**robot, "bytes_compressed": 3000, "fits_compressed": True, "compressed_certified": False}
    assert "not certified" in advice({"robots": [uncertified], "compressed": {}}, 31)


# --- 3-D plans ---------------------------------------------------------------------------------------


def test_every_plans_robots_sit_on_the_ground_below_their_start():
    """Motion capture finds a robot where it sits before take-off: below its start, in 3-D too."""
    from mrfswarm.export.crazyswarm2 import crazyflies_config, starts_of
    from support.flight3d import window_flight

    trs = window_flight(3).trajectories
    starts = starts_of(trs)
    assert starts.shape == (3, 3) and np.array_equal(starts, [tr.evaluate(0.0) for tr in trs])
    robots = crazyflies_config(starts)["robots"]
    assert [r["initial_position"] for r in robots.values()] == [[*s[:2], 0.0] for s in starts.tolist()]
    assert len(set(s[2] for s in starts.tolist())) > 1  # different heights, all flown from the ground
    flat = crazyflies_config(starts[:, :2])["robots"]
    assert [r["initial_position"] for r in flat.values()] == [[*s[:2], 0.0] for s in starts.tolist()]


def test_cflib_upload_flies_a_3d_compressed_plan(tmp_path):
    """A 3-D plan's folder as a run writes it (crazyflies.yaml, compressed.json with z in the points): the script
    uploads cflib's packing of the certified bytes, z control points included."""
    import json

    from cflib.crazyflie.mem import MemoryElement, TrajectoryMemory

    from mrfswarm.export import cflib_
    from mrfswarm.export.crazyswarm2 import starts_of, write_crazyswarm2
    from mrfswarm.outputs import compressed_json
    from support.flight3d import window_flight

    trs = window_flight(3).trajectories
    write_crazyswarm2(starts_of(trs), tmp_path)
    comp = cflib_.compress(trs, altitude=1.0, v_max=3.0)
    (tmp_path / "crazyflie" / "compressed.json").write_text(json.dumps(compressed_json(comp)))
    script = load_script(tmp_path / "crazyflie" / "cflib_upload.py", "cflib_upload_3d")
    with pytest.raises(SystemExit, match="no result.json"):  # this folder has no certificate to read ...
        script.pieces([2], True, tmp_path)
    script.not_certified = lambda plan: []  # ... the packing is this test's subject (the certificate's: above)
    assert script.compressed_plan(tmp_path).z_mm is None
    elements, origin = script.pieces([2], True, tmp_path)
    assert np.allclose(script.start_of(elements[2], True), trs[2].evaluate(0.0), atol=1e-3)
    # what the drone stores, exactly (the elements' floats carry half a millimetre / millisecond more)
    assert script.start_of(elements[2], True) == tuple(v / 1000 for v in comp.start_mm(2))
    assert script.duration_of(elements[2], True) == (comp.knots_ms[2][-1] - comp.knots_ms[2][0]) / 1000
    assert elements[2][0].x != script.start_of(elements[2], True)[0]
    # --fly takes every robot off to the highest start, as fly.py does (not robot 0's)
    every, _ = script.pieces([0, 1, 2], True, tmp_path)
    top = max(tr.evaluate(0.0)[2] for tr in trs)
    assert trs[0].evaluate(0.0)[2] < top
    assert script.takeoff_altitude(every, True) == pytest.approx(top, abs=1e-3)
    link = FakeLink()
    memory = TrajectoryMemory(id=1, type=MemoryElement.TYPE_TRAJ, size=4096, mem_handler=link)
    cf = types.SimpleNamespace(mem=types.SimpleNamespace(get_mems=lambda kind: [memory]), send_packet=lambda p: None,
                               link_uri="radio://fake")
    from cflib.crazyflie.high_level_commander import HighLevelCommander

    cf.high_level_commander = HighLevelCommander(cf)
    assert script.upload(cf, elements[2], True) == 8 + 45 * trs[2].pieces + 3
    assert link.data == cflib_.pack_compressed(comp, 2)
    dec = cflib_.decode_compressed(link.data, origin, dim=3)
    t = np.linspace(0.0, dec.duration, 2001)
    assert np.abs(dec.evaluate(t) - trs[2].evaluate(np.minimum(t, trs[2].duration))).max() < 3e-3


def test_fly_py_flies_a_plan_of_one_piece(tmp_path, monkeypatch):
    """Robots that start at the goal fly one hover piece; Crazyswarm2's loadcsv failed on a CSV of one row
    ("IndexError: invalid index to scalar variable", a 3-D tour). fly.py hands it the same polynomial in two
    halves; without that, this fake (which reads as Crazyswarm2 does) raises the same IndexError."""
    cfg = tmp_path / "onestep.toml"
    cfg.write_text("""[scenario]
map = { kind = "free", size = [8, 8, 6], resolution = 0.25, origin = [0.125, 0.125, 0.125] }
start = { positions = [[0.875, 0.875, 0.875], [1.375, 0.875, 0.875]] }
goal = [1.125, 1.125, 0.875]
robot_radius = 0.1
downwash = 2.5
[simulation]
enabled = false
""")
    out = tmp_path / "out"
    assert main(["run", str(cfg), "--out", str(out), "--workers", "1"]) == 0
    csv = read_uav_csv(out / "trajectories" / "robot_1.csv", dim=4)
    assert csv.pieces == 1
    calls = []
    monkeypatch.setattr(sys, "modules", {**sys.modules, **fake_crazyflie_py(calls, ["cf1", "cf2"])})
    made = []
    fly = load_script(out / "crazyswarm2" / "fly.py", "fly_one_piece")
    halves = fly.loadable
    monkeypatch.setattr(fly, "loadable", lambda p: made.append(halves(p)) or made[-1])
    fly.main([])
    assert len(made) == 2 and not any(p.exists() for p in made)  # the temporary halves are removed
    up = next(c[4] for c in calls if c[0] == "upload" and c[1] == "cf2")
    assert len(up.polynomials) == 2 and up.duration == pytest.approx(csv.durations.sum(), abs=1e-12)
    half = up.polynomials[0].duration
    for t in np.linspace(0.0, up.duration, 9):  # the same flight: the second half is the shifted polynomial
        p = up.polynomials[0] if t <= half else up.polynomials[1]
        tt = t if t <= half else t - half
        got = [np.polynomial.polynomial.polyval(tt, q.p) for q in (p.px, p.py, p.pz)]
        np.testing.assert_allclose(got, csv.evaluate(t)[:3], atol=1e-12)
    assert sorted(f.name for f in (out / "trajectories").iterdir()) == ["robot_0.csv", "robot_1.csv"]


def test_a_piece_written_in_two_halves_is_the_same_polynomial(run_dir, tmp_path):
    """fly.loadable's halves of a piece of degree 7 on every axis evaluate as the piece does."""
    fly = load_script(run_dir / "crazyswarm2" / "fly.py", "fly_halves")
    rng = np.random.default_rng(3)
    row = np.concatenate([[1.7], rng.normal(size=32)])
    header = (run_dir / "trajectories" / "robot_0.csv").read_text().splitlines()[0]
    path = tmp_path / "one.csv"
    path.write_text(header + "\n" + ",".join(repr(float(v)) for v in row) + "\n")
    halves = np.loadtxt(fly.loadable(path), delimiter=",", skiprows=1, ndmin=2)
    assert halves.shape == (2, 33) and np.allclose(halves[:, 0], 0.85)
    for t in np.linspace(0.0, 1.7, 11):
        h = halves[0] if t <= 0.85 else halves[1]
        tt = t if t <= 0.85 else t - 0.85
        for k in range(4):
            assert np.polynomial.polynomial.polyval(tt, h[1 + 8 * k:9 + 8 * k]) == pytest.approx(
                np.polynomial.polynomial.polyval(t, row[1 + 8 * k:9 + 8 * k]), abs=1e-9)
    assert fly.loadable(run_dir / "trajectories" / "robot_0.csv") == run_dir / "trajectories" / "robot_0.csv"


def test_cflib_upload_help_says_how_many_compressed_pieces_fit_in_2d_and_3d(monkeypatch, capsys):
    """The help said "fit 131 instead of 31" for every plan, but a 3-D plan's pieces store z too (45 bytes, not
    31): 90 fit. The counts are cflib's own packing into the 4096-byte memory."""
    from cflib.crazyflie.mem import CompressedSegment, CompressedStart

    from mrfswarm.export.cflib_ import MEMORY_BYTES
    from mrfswarm.export.crazyswarm2 import SCRIPTS

    def most(dim):
        axes = [[0.001] * 7] * dim + [[]] * (3 - dim)
        n = 0
        while len(b"".join(bytes(e.pack()) for e in [CompressedStart(0.0, 0.0, 1.0, 0.0)]
                           + [CompressedSegment(0.5, *axes, [])] * (n + 1) + [CompressedSegment(0.0, [], [], [], [])])) \
                <= MEMORY_BYTES:
            n += 1
        return n

    script = load_script(SCRIPTS / "cflib_upload.py", "cflib_upload_help")
    with pytest.raises(SystemExit) as e:
        script.main(["--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert e.value.code == 0
    assert f"fit {most(2)} instead of 31" in text and f"{most(3)} in a 3-D plan" in text, text


@pytest.mark.parametrize("origin_z, warned", [(0.25, False), (1.25, True)])
def test_a_map_whose_floor_is_above_the_ground_is_a_warning_of_the_run(tmp_path, caplog, origin_z, warned):
    """A voxel map with its floor at z = 1 m (origin z 1.25, 0.5 m voxels) was exported without a word: the robots
    sit on the ground at z = 0, as crazyflies.yaml says, and the scripts take off from there and land to 4 cm through
    the space below the map, which the plan counts as a wall (a 3-D tour). The floor at z = 0 says nothing."""
    toml = tmp_path / "raised.toml"
    z = origin_z + 0.5
    toml.write_text(f"""
[scenario]
map = {{ kind = "free", size = [6, 4, 3], resolution = 0.5, origin = [0.25, 0.25, {origin_z}] }}
start = {{ positions = [[0.25, 0.25, {z}], [0.25, 1.25, {z}]] }}
goal = [2.25, 0.75, {z}]
robot_radius = 0.2
[simulation]
enabled = false
""")
    with caplog.at_level("WARNING"):
        assert main(["run", str(toml), "--out", str(tmp_path / "run")]) == 0
    said = f"the map's floor is at z = {origin_z - 0.25:g} m, above the ground at z = 0"
    assert (said in caplog.text) == warned, caplog.text
    assert (said in (tmp_path / "run" / "crazyswarm2" / "crazyflies.yaml").read_text()) == warned
