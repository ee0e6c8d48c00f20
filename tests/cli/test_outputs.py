"""`mrfswarm run --out`: a folder never mixes two runs and is never left half-written."""

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from mrfswarm import outputs
from mrfswarm.cli import main
from support.repository import EXPERIMENTS, ROOT


def config(tmp_path: Path, n: int) -> Path:
    p = tmp_path / f"swarm{n}.toml"
    starts = ", ".join(f"[{3 + 2 * i}, 5]" for i in range(n))
    p.write_text(f"[scenario]\nmap = {{ kind = \"free\", size = [20, 12] }}\nstart = {{ positions = [{starts}] }}\n"
                 "goal = [15, 9]\n[interaction]\nk = 2\n[mrf]\nmax_steps = 6\n[simulation]\nenabled = false\n")
    return p


def run(tmp_path, n, out, *extra):
    return main(["run", str(config(tmp_path, n)), "--out", str(out), *extra])


def snapshot(folder: Path) -> dict:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_six_then_five_robots_refused_then_overwritten(tmp_path, capsys):
    out = tmp_path / "out"
    assert run(tmp_path, 6, out) == 0
    first = snapshot(out)
    assert "trajectories/robot_5.csv" in first and json.loads(first["result.json"])["complete"] is True
    capsys.readouterr()
    assert run(tmp_path, 5, out) == 2  # refused before planning
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "already holds a run" in err and "--overwrite" in err and str(out) in err
    assert "in Python" not in err and "overwrite=True" not in err, err  # the command's way only
    assert snapshot(out) == first  # intact
    assert run(tmp_path, 5, out, "--overwrite") == 0
    second = snapshot(out)
    assert "trajectories/robot_5.csv" not in second and "trajectories/robot_4.csv" in second
    res = json.loads(second["result.json"])
    assert res["n_robots"] == 5 and res["complete"] is True and len(res["crazyflie"]["robots"]) == 5
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".out.")]  # no staging or old folder left


def test_a_failed_run_does_not_replace_a_complete_one(tmp_path, capsys):
    """--overwrite and a plan that fails after the discrete stage: what it computed replaced the complete run (a tour);
    now the complete run stays and the failed one goes beside it, DIR.failed, said in the error line."""
    out = tmp_path / "out"
    assert run(tmp_path, 3, out) == 0
    first = snapshot(out)
    capsys.readouterr()
    # a Morse zeta this large leaves no move that lowers the energy: "the swarm cannot move", after the discrete stage
    assert run(tmp_path, 3, out, "--overwrite", "--set", "interaction.zeta=1e300") == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "the swarm cannot move" in err and f"the run in {out} is kept" in err
    assert snapshot(out) == first
    failed = json.loads((tmp_path / "out.failed" / "result.json").read_text())
    assert failed["failure"].startswith("the swarm cannot move") and failed["complete"] is True
    # again: the failed folder is a run's folder, replaced; a failed run over a failed one replaces it as before
    assert run(tmp_path, 3, out, "--overwrite", "--set", "interaction.zeta=1e300") == 2 and snapshot(out) == first
    assert run(tmp_path, 3, tmp_path / "out.failed", "--overwrite", "--set", "interaction.zeta=1e300") == 2
    assert not (tmp_path / "out.failed.failed").exists()


def test_a_folder_that_is_not_a_run_is_never_replaced(tmp_path, capsys):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("keep me")
    assert run(tmp_path, 3, out, "--overwrite") == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "not an mrfswarm run's" in err and "notes.txt" in err
    assert (out / "notes.txt").read_text() == "keep me" and len(list(out.iterdir())) == 1


@pytest.mark.parametrize("name", [".", ".."])
def test_the_current_folder_is_refused_before_planning(tmp_path, monkeypatch, capsys, name):
    """--out . planned, then failed on its own staging folder (empty folder) or with a traceback renaming '.' (a
    run's folder with --overwrite); a run replaces its folder as a whole, so the current folder is refused."""
    here = tmp_path / "here"
    here.mkdir()
    (here / "result.json").write_text("{}")  # a run's folder: --overwrite would replace it
    monkeypatch.chdir(here)
    assert run(tmp_path, 3, name, "--overwrite") == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "is the current folder or holds it" in err
    assert sorted(p.name for p in here.iterdir()) == ["result.json"] and (here / "result.json").read_text() == "{}"


def test_an_empty_folder_is_used(tmp_path):
    out = tmp_path / "empty"
    out.mkdir()
    assert run(tmp_path, 3, out) == 0 and json.loads((out / "result.json").read_text())["complete"] is True


def test_animate_without_a_smoothed_flight_is_said(tmp_path, capsys):
    """--animate with the continuous stage off wrote no animation.gif and said nothing (a tour): one warning line."""
    out = tmp_path / "out"
    assert run(tmp_path, 3, out, "--animate", "--set", "smoothing.enabled=false") == 0
    err = [line for line in capsys.readouterr().err.splitlines() if "animat" in line]  # (3 steps: max_steps said too)
    assert len(err) == 1 and err[0].startswith("mrfswarm: warning: --animate not used") and "animation.gif" in err[0]
    assert (out / "result.json").is_file() and not (out / "animation.gif").exists()


def test_a_late_writer_failing_leaves_the_old_run_intact(tmp_path, monkeypatch):
    out = tmp_path / "out"
    assert run(tmp_path, 6, out) == 0
    first = snapshot(out)

    def broken(result, out):  # the last writer before result.json
        raise KeyboardInterrupt

    monkeypatch.setattr(outputs, "write_crazyflie_outputs", broken)
    assert run(tmp_path, 5, out, "--overwrite") == 130
    assert snapshot(out) == first
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []  # the staging folder is gone
    fresh = tmp_path / "fresh"
    assert run(tmp_path, 5, fresh) == 130
    assert not fresh.exists()  # nothing complete-looking, nothing at all


def test_an_interrupt_while_the_runs_are_swapped_leaves_one_whole_run(tmp_path, monkeypatch):
    """Ctrl-C between setting the old run aside and renaming the new one into place left --out missing (the old run
    only in a hidden .out.old-* folder); Ctrl-C while the old run was deleted left that folder beside --out."""
    import shutil

    out = tmp_path / "out"
    assert run(tmp_path, 6, out) == 0
    first = snapshot(out)
    rename, rmtree = os.rename, shutil.rmtree

    def interrupted_rename(src, dst):
        if Path(src).name.startswith(".out.partial-"):
            raise KeyboardInterrupt
        rename(src, dst)

    monkeypatch.setattr(outputs.os, "rename", interrupted_rename)
    assert run(tmp_path, 5, out, "--overwrite") == 130
    assert snapshot(out) == first  # the old run is back in place
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []
    monkeypatch.setattr(outputs.os, "rename", rename)

    def interrupted_rmtree(path, *args, **kwargs):
        monkeypatch.setattr(outputs.shutil, "rmtree", rmtree)  # once
        raise KeyboardInterrupt

    monkeypatch.setattr(outputs.shutil, "rmtree", interrupted_rmtree)
    assert run(tmp_path, 5, out, "--overwrite") == 130
    assert json.loads((out / "result.json").read_text())["n_robots"] == 5  # the new run, whole
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []  # the old one not left beside


def test_a_folder_that_cannot_be_written_is_refused_before_anything_runs(tmp_path, monkeypatch, capsys):
    """--out on a read-only file system (or in a folder without write permission) planned in full and then lost the
    plan to a traceback from the first write (`mrfswarm run`, `smooth` and `sweep` alike)."""
    import mrfswarm.pipeline

    locked = tmp_path / "locked"
    locked.mkdir()
    access = os.access
    monkeypatch.setattr(os, "access", lambda path, mode, **kw: Path(path) != locked and access(path, mode, **kw))
    monkeypatch.setattr(mrfswarm.pipeline, "plan", lambda *a, **kw: pytest.fail("planned"))
    waypoints = tmp_path / "w.csv"
    waypoints.write_text("x,y\n0,0\n3,4\n")
    for argv in (["run", str(config(tmp_path, 3)), "--out", str(locked / "a" / "run")],
                 ["smooth", str(waypoints), "--out", str(locked / "traj.csv")],
                 ["sweep", str(config(tmp_path, 3)), "--grid", "interaction.k_a=8,14", "--out", str(locked / "sw")]):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "cannot be written" in err and "not writable" in err and str(locked) in err
    assert list(locked.iterdir()) == []


def test_a_write_the_file_system_refuses_is_one_line_and_keeps_the_old_run(tmp_path, monkeypatch, capsys):
    out = tmp_path / "out"
    assert run(tmp_path, 6, out) == 0
    first = snapshot(out)

    def full(result, out):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(outputs, "write_crazyflie_outputs", full)
    capsys.readouterr()
    assert run(tmp_path, 5, out, "--overwrite") == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "cannot write the outputs to" in err and "No space left on device" in err
    assert snapshot(out) == first
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []


def test_killed_run_leaves_no_result(tmp_path):
    """Kill a real process while it writes its outputs: --out gets no result.json (nor anything)."""
    out = tmp_path / "out"
    cfg = config(tmp_path, 6)
    slow = tmp_path / "slow.py"  # the real CLI, with figures that take a while so the kill lands while writing
    slow.write_text("import sys, time\nfrom mrfswarm import plots\nreal = plots.save_figure\n"
                    "def save(*a, **k):\n    print('writing', flush=True)\n    time.sleep(30)\n"
                    "plots.save_figure = save\nfrom mrfswarm.cli import main\nsys.exit(main(sys.argv[1:]))\n")
    proc = subprocess.Popen([sys.executable, str(slow), "run", str(cfg), "--out", str(out)], cwd=ROOT,
                            stdout=subprocess.PIPE, env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert proc.stdout.readline().strip() == b"writing"
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=30)
    assert not out.exists()
    partial = [p for p in tmp_path.iterdir() if p.name.startswith(".out.partial-")]
    assert len(partial) == 1 and not (partial[0] / "result.json").exists()  # the hidden staging folder only
    assert run(tmp_path, 6, out) == 0  # and the next run is not bothered by it


def _children(pid: int) -> list[int]:
    """The live processes whose parent is ``pid`` (from /proc)."""
    out = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid and fields[0] != "Z":
            out.append(int(stat.parent.name))
    return out


def _alive(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads /proc")
def test_sigterm_stops_the_workers_and_writes_nothing(tmp_path):
    """SIGTERM killed the command outright and its pool's workers lived on, holding its pipes (a caller waiting
    for the end of its output hung). Now it stops as on Ctrl-C: exit 143, one line, the workers gone, no folder."""
    out = tmp_path / "out"
    cfg = tmp_path / "swarm14.toml"  # two chunks: the window QPs go to worker processes
    starts = ", ".join(f"[{3 + 2 * i}, 5]" for i in range(14))
    cfg.write_text(f"[scenario]\nmap = {{ kind = \"free\", size = [40, 12] }}\nstart = {{ positions = [{starts}] }}\n"
                   "goal = [30, 9]\n[interaction]\nk = 2\n[mrf]\nmax_steps = 6\n[simulation]\nenabled = false\n")
    slow = tmp_path / "slow.py"  # the real CLI, its window QPs slow so the signal lands while the workers work
    slow.write_text("import sys, time\nimport mrfswarm.continuous.receding_horizon as rh\nreal = rh.solve_window\n"
                    "def solve(*a, **k):\n    sys.stdout.write('solving\\n'); sys.stdout.flush()\n    time.sleep(0.5)\n    return real(*a, **k)\n"
                    "rh.solve_window = solve\nfrom mrfswarm.cli import main\nsys.exit(main(sys.argv[1:]))\n")
    proc = subprocess.Popen([sys.executable, str(slow), "run", str(cfg), "--out", str(out), "--workers", "2"],
                            cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            env={**os.environ, "PYTHONPATH": str(ROOT)})
    workers: list[int] = []
    while len(workers) < 2:  # until the pool is up (its workers start with their first chunks)
        line = proc.stdout.readline()  # one write a line, atomic on a pipe: whole lines from the two workers
        assert line == b"solving\n" and proc.poll() is None, line
        workers = _children(proc.pid)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)  # returns: nothing holds the pipes
    assert proc.returncode == 143 and err.decode().strip().splitlines()[-1] == "mrfswarm: terminated"
    assert not [pid for pid in workers if _alive(pid)]
    assert not out.exists() and not [p for p in tmp_path.iterdir() if p.name.startswith(".out.")]


@pytest.mark.parametrize("result", [None, {"discrete": None}])
def test_write_outputs_of_no_result_is_one_line_before_any_folder(tmp_path, result):
    """write_outputs(None) ended in "AttributeError: 'NoneType' object has no attribute 'discrete_paths_world'",
    after making the folder's parent and a staging folder."""
    out = tmp_path / "runs" / "one"
    with pytest.raises(TypeError, match=f"^write_outputs needs the Result of mrfswarm.plan, got {type(result).__name__}$"):
        outputs.write_outputs(result, out)
    assert not (tmp_path / "runs").exists()


def test_check_output_dir_guards(tmp_path):
    from mrfswarm.errors import ExportError

    run_dir = tmp_path / "r"
    run_dir.mkdir()
    (run_dir / "result.json").write_text("{}")
    outputs.check_output_dir(run_dir, overwrite=True)
    with pytest.raises(ExportError, match=r"already holds a run .*\(in Python: overwrite=True\)"):
        outputs.check_output_dir(run_dir)
    outputs.check_output_dir(tmp_path / "nowhere")



@pytest.mark.parametrize("d", [2, 3])
def test_discrete_csv_has_a_z_column_in_every_run(tmp_path, d):
    """``step,robot,x,y,z``: a 3-D run's voxel centres as they are, a 2-D run's cells at the altitude."""
    import numpy as np

    rng = np.random.default_rng(d)
    paths = rng.integers(-5, 30, size=(4, 3, d)) * 0.5  # (T + 1, N, d) metres
    path = outputs.write_discrete_csv(tmp_path / "p.csv", paths, altitude=1.25)
    assert path.read_text().splitlines()[0] == "step,robot,x,y,z"
    data = np.loadtxt(path, delimiter=",", skiprows=1)
    assert data.shape == (12, 5)
    assert np.array_equal(data[:, 0], np.repeat(np.arange(4), 3)) and np.array_equal(data[:, 1], np.tile(np.arange(3), 4))
    assert np.array_equal(data[:, 2:2 + d], paths.reshape(-1, d))
    assert np.array_equal(data[:, 4], paths[..., 2].ravel() if d == 3 else np.full(12, 1.25))


def _voxel_config(tmp_path: Path, smoothing: bool) -> Path:
    """Three robots in a free 10 x 6 x 4 voxel room, 0.5 m voxels (z of a voxel centre: 0.5 k + 0.25)."""
    p = tmp_path / "room3d.toml"
    p.write_text("[scenario]\nmap = { kind = \"free\", size = [10, 6, 4], resolution = 0.5, origin = [0.25, 0.25, 0.25] }\n"
                 "start = { positions = [[0.75, 0.75, 0.75], [0.75, 1.75, 1.25], [0.75, 2.75, 0.75]] }\n"
                 "goal = [4.25, 1.75, 1.75]\ndownwash = 2.0\nrobot_radius = 0.1\n[interaction]\nk = 2\n"
                 f"[mrf]\nmax_steps = 12\n[smoothing]\nenabled = {str(smoothing).lower()}\n")
    return p


@pytest.mark.parametrize("smoothing", [False, True], ids=["discrete", "smoothed"])
def test_a_3d_run_writes_z_projections_and_the_interactive_view(tmp_path, smoothing):
    """End to end on a voxel map: discrete_paths.csv with the voxel centres' z, the projected figures, the
    self-contained scene.html and, smoothed and flown, the animation and the tracking error per axis."""
    import csv

    out = tmp_path / "out"
    cfg = _voxel_config(tmp_path, smoothing)
    assert main(["run", str(cfg), "--out", str(out), "--animate", "--workers", "1"]) == 0
    rows = list(csv.DictReader(open(out / "discrete_paths.csv")))
    assert list(rows[0]) == ["step", "robot", "x", "y", "z"]
    z = {float(r["z"]) for r in rows}
    assert {0.75, 1.25} <= z and all((v - 0.25) / 0.5 == round((v - 0.25) / 0.5) for v in z)  # voxel centres
    html = (out / "figures" / "scene.html").read_text()
    assert "Plotly.newPlot" in html and "<script src" not in html
    from PIL import Image

    w, h = Image.open(out / "figures" / "discrete_paths.png").size
    assert w > h  # the three projections of a 5 x 3 x 2 m room side by side
    res = json.loads((out / "result.json").read_text())
    assert res["complete"] is True
    if smoothing:
        assert (out / "animation.gif").is_file() and (out / "figures" / "robot_xyz.png").is_file()
        assert '"trajectories"' in html
        sim = res["simulation"]
        assert set(sim["max_tracking_error_axis_m"]) == {"x", "y", "z"}
        assert max(sim["max_tracking_error_axis_m"].values()) <= sim["max_tracking_error_m"]
        ys = yaml_robots(out)
        assert {p[2] for p in ys} == {0.0}  # initial_position: on the ground below the start


def test_a_3d_runs_summary_line_says_its_separation_is_downwash_scaled(tmp_path, capsys):
    """The line printed "min separation 1.00 m discrete" where result.json's metric is sqrt(dx² + dy² + (dz/c)²):
    a plain distance would be read; a 2-D run's (downwash without effect there) says nothing more."""
    assert main(["run", str(_voxel_config(tmp_path, False)), "--out", str(tmp_path / "a")]) == 0
    assert "min separation (downwash-scaled) " in capsys.readouterr().out
    flat = tmp_path / "flat.toml"
    flat.write_text("[scenario]\nmap = { kind = \"free\", size = [10, 6] }\ndownwash = 2.0\n"
                    "start = { positions = [[2, 2], [2, 4]] }\ngoal = [8, 3]\n[mrf]\nmax_steps = 4\n"
                    "[smoothing]\nenabled = false\n")
    assert main(["run", str(flat), "--out", str(tmp_path / "b")]) == 0
    out = capsys.readouterr().out
    assert "min separation " in out and "downwash-scaled" not in out


@pytest.mark.parametrize("sets, said", [([], "smooth (piqp), "),
                                        (["smoothing.time_refinement=true", "smoothing.refinement=\"nlp\"",
                                          "smoothing.nlp=slsqp"], "smooth (piqp, refined by slsqp), ")])
def test_the_summary_line_names_the_nlp_backend_that_refined(tmp_path, capsys, sets, said):
    """--nlp sqpmethod printed only "(piqp)" (a solver tour); result.json's nlp was right."""
    args = [a for s in ["simulation.enabled=false", *sets] for a in ("--set", s)]
    assert main(["run", str(EXPERIMENTS / "corridor.toml"), "--out", str(tmp_path / "a"), *args]) == 0
    assert said in capsys.readouterr().out


def yaml_robots(out: Path) -> list:
    import yaml

    robots = yaml.safe_load((out / "crazyswarm2" / "crazyflies.yaml").read_text())["robots"]
    return [r["initial_position"] for r in robots.values()]


@pytest.mark.parametrize("mask", [0o022, 0o027])
def test_a_runs_files_and_folders_get_the_modes_the_umask_gives(tmp_path, mask):
    """Every file of a run is written under a temporary name (mkstemp: owner-only, 0600) and renamed into place;
    it gets the mode a file created the usual way would have (0666 less the umask), as its folders get 0777 less
    the umask: a colleague or a web server that may read the folder may read the run. The same for a CSV written
    by the trajectory module."""
    from mrfswarm.trajectory.uav_csv import write_text_atomic

    old = os.umask(mask)
    try:
        out = tmp_path / "out"
        assert run(tmp_path, 3, out) == 0
        write_text_atomic(tmp_path / "robot.csv", "duration\n")
    finally:
        os.umask(old)
    files = [p for p in out.rglob("*") if p.is_file()] + [tmp_path / "robot.csv"]
    folders = [out] + [p for p in out.rglob("*") if p.is_dir()]
    assert len(files) > 10 and len(folders) > 3
    assert {oct(p.stat().st_mode & 0o777) for p in files} == {oct(0o666 & ~mask)}
    assert {oct(p.stat().st_mode & 0o777) for p in folders} == {oct(0o777 & ~mask)}


def test_the_command_interrupted_ignores_a_second_ctrl_c_on_its_way_out(tmp_path, monkeypatch):
    """Run as the command (its own argv), an interrupted run ignores SIGINT once it has said so: a second one
    during the interpreter's exit (the worker pool joining its threads) printed concurrent.futures' traceback
    after "mrfswarm: interrupted" in 6 of 12 runs of swarm100 signalled twice 10 ms apart (0 of 12 since).
    Called with an argv (a caller's process, these tests), the handler is the caller's to keep."""
    import mrfswarm.cli.run as run_command
    from mrfswarm import cli

    def interrupted(args):
        raise KeyboardInterrupt

    monkeypatch.setattr(run_command, "run", interrupted)
    cfg = config(tmp_path, 3)
    before = signal.getsignal(signal.SIGINT)
    try:
        assert cli.main(["run", str(cfg), "--out", str(tmp_path / "a")]) == 130
        assert signal.getsignal(signal.SIGINT) is before  # a caller's argv: untouched
        monkeypatch.setattr(sys, "argv", ["mrfswarm", "run", str(cfg), "--out", str(tmp_path / "b")])
        assert cli.main() == 130
        assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
    finally:
        signal.signal(signal.SIGINT, before)


def test_a_3d_formation_runs_summary_line_without_a_goal(tmp_path, capsys):
    """A 3-D formation flight (no goal) with downwash ended in a TypeError traceback after writing its run: the
    summary line took the run's dimension from the goal's length."""
    cfg = tmp_path / "formation.toml"
    cfg.write_text("[scenario]\nmap = { kind = \"free\", size = [6, 6, 4], origin = [0, 0, 0.5] }\ndownwash = 2.0\n"
                   "start = { positions = [[1, 1, 1.5], [3, 1, 1.5], [1, 3, 1.5], [3, 3, 1.5]] }\n"
                   "[mrf]\nmax_steps = 3\n[smoothing]\nenabled = false\n")
    assert main(["run", str(cfg), "--out", str(tmp_path / "out")]) == 0
    assert "min separation (downwash-scaled) " in capsys.readouterr().out
