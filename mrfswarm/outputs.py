"""Writing a run's outputs: ``result.json``, ``discrete_paths.csv``, trajectories, figures, the Crazyflie files.

A run's folder is never mixed with another run's nor left half-written
(:func:`write_outputs`): the outputs are written into a fresh hidden folder beside it,
``result.json`` last (with ``"complete": true``), and that folder is renamed into place at
the end. So an interrupted run leaves the folder as it was (a killed one may leave the
hidden ``.NAME.partial-*`` folder beside it), and a folder with a ``result.json`` is a
whole run. A folder that already holds files is refused, unless ``overwrite`` and it is a
run's folder (it holds a ``result.json``): then it is replaced as a whole, the old one
moved aside and deleted only once the new one is in place. Every single file is also
written to a temporary name and renamed (:func:`atomic_write`).
"""

from __future__ import annotations

import json
import logging
import os
import shutil
import tempfile
import warnings
from functools import partial
from pathlib import Path

import numpy as np

from mrfswarm import plots
from mrfswarm.atomic import atomic_write, not_writable, umask
from mrfswarm.errors import ExportError, OutputExistsError, UnusedSettingWarning
from mrfswarm.pipeline import Result

log = logging.getLogger(__name__)

RUN_MARKER = "result.json"
"""The file that makes a folder a run's folder (written last)."""


def write_json(path: Path, data: dict) -> Path:
    return atomic_write(path, lambda p: p.write_text(json.dumps(data, indent=2) + "\n"))


def write_discrete_csv(path: Path, paths_world: np.ndarray, altitude: float) -> Path:
    """``step,robot,x,y,z`` in metres, one row per robot per step.

    ``paths_world`` is (T + 1, N, d): a 3-D run's voxel centres, or a 2-D run's cell
    centres, which fly at ``altitude`` (their z column).
    """
    T1, N, d = paths_world.shape
    steps = np.repeat(np.arange(T1), N)
    robots = np.tile(np.arange(N), T1)
    xyz = np.empty((T1 * N, 3))
    xyz[:, :d] = paths_world.reshape(-1, d)
    if d == 2:
        xyz[:, 2] = altitude

    def write(p: Path) -> None:
        with open(p, "w") as f:
            f.write("step,robot,x,y,z\n")
            for a in range(0, len(xyz), 100_000):  # one formatting call per block of rows
                b = a + 100_000
                rows = zip(steps[a:b].tolist(), robots[a:b].tolist(), *xyz[a:b].T.tolist())
                f.write("".join(f"{s},{r},{x:.6g},{y:.6g},{z:.6g}\n" for s, r, x, y, z in rows))

    return atomic_write(path, write)


def check_output_dir(out: Path, overwrite: bool = False, marker: str = RUN_MARKER, what: str = "run") -> None:
    """Refuse an output folder that holds files, unless ``overwrite`` and it is a run's folder (one holding
    ``marker``; ``what`` names it in the messages: ``mrfswarm sweep`` checks its folders as a sweep's).

    Raises
    ------
    ExportError
        ``out`` is not empty and ``overwrite`` is false; or ``out`` holds files but no
        ``marker`` (not a run's folder: ``overwrite`` never deletes that); or ``out`` is the
        current folder or holds it (a run replaces its folder as a whole, by renaming); or no folder can be made
        where ``out`` goes (a read-only file system, no permission).
    """
    out = Path(out)
    try:
        here = Path.cwd().resolve()
    except OSError:  # the current folder was deleted: no output folder can hold it
        here = None
    folder = out.resolve()
    if here is not None and (folder == here or folder in here.parents):
        raise ExportError(f"output folder {str(out)!r} is the current folder or holds it: a {what} replaces its output "
                          f"folder as a whole; give --out a folder of its own (e.g. --out {what}1)")
    # the folder is made (or replaced) beside itself, in its nearest existing parent
    why = not_writable(next(p for p in (folder.parent, *folder.parent.parents) if p.is_dir()))
    if why is not None:
        raise ExportError(f"output folder {str(out)!r} cannot be written: {why}")
    if not out.is_dir():
        return
    names = sorted(p.name + "/" * p.is_dir() for p in out.iterdir())
    if not names:
        return
    listed = ", ".join(names[:4]) + (", ..." if len(names) > 4 else "")
    if not (out / marker).is_file():
        raise ExportError(f"output folder {str(out)!r} holds files that are not an mrfswarm {what}'s ({listed}: no "
                          f"{marker}); choose another --out")
    if not overwrite:
        held = f"output folder {str(out)!r} already holds a {what} ({listed}); give --overwrite"
        raise OutputExistsError(f"{held} (in Python: overwrite=True) to replace it, or another --out",
                                f"{held} to replace it, or another --out")


def set_aside(out: Path) -> Path | None:
    """Move the folder ``out`` (if it holds anything) to a hidden folder beside it, and return that (None if there
    was nothing): what replaces it is written in its place, the old one deleted once that is complete."""
    out = Path(out)
    if not out.is_dir() or not any(out.iterdir()):
        return None
    old = Path(tempfile.mkdtemp(dir=out.parent, prefix=f".{out.name}.old-"))
    os.rename(out, old / out.name)
    return old


def write_outputs(result: Result, out: Path, animate: bool = False, overwrite: bool = False) -> list[Path]:
    """Everything a run computed, into ``out`` as a whole (module docstring): discrete outputs,
    trajectories, continuous figures, GIF, the Crazyflie files, for a 3-D run the interactive view
    (``figures/scene.html``), and ``result.json`` last.

    Raises
    ------
    TypeError
        ``result`` is not a :class:`~mrfswarm.pipeline.Result`.
    ExportError
        ``out`` holds files (see :func:`check_output_dir`).
    """
    if not isinstance(result, Result):  # None failed deep in the discrete outputs, an AttributeError (a library tour)
        raise TypeError(f"write_outputs needs the Result of mrfswarm.plan, got {type(result).__name__}")
    out = Path(out)
    check_output_dir(out, overwrite)
    if animate and result.continuous is None:  # the GIF draws the smoothed flight (a tour's went missing without a word)
        warnings.warn("--animate not used: the run has no smoothed flight to animate (smoothing.enabled = false), "
                      "no animation.gif", UnusedSettingWarning, stacklevel=2)
    out.parent.mkdir(parents=True, exist_ok=True)
    stage = Path(tempfile.mkdtemp(dir=out.parent, prefix=f".{out.name}.partial-"))
    log.info("writing the outputs to %s%s", out, " (with the animation)" if animate else "")
    try:
        os.chmod(stage, 0o777 & ~umask())  # as a folder made by mkdir would be
        written = write_discrete_outputs(result, stage)
        if result.continuous is not None:
            written += write_continuous_outputs(result, stage, animate)
        if result.scenario.grid.ndim == 3:
            written.append(write_scene(result, stage))
        written.append(write_json(stage / RUN_MARKER, {**result.summary(), "complete": True}))
        check_output_dir(out, overwrite)  # nobody wrote into it meanwhile
        _swap(stage, out)
    except BaseException as e:
        shutil.rmtree(stage, ignore_errors=True)
        if isinstance(e, OSError):  # the file system's refusal (full, a mount point to replace): one line
            raise ExportError(f"cannot write the outputs to {str(out)!r}: {e}") from e
        raise
    return [out / p.relative_to(stage) for p in written]


def _swap(stage: Path, out: Path) -> None:
    """Put ``stage`` in the place of ``out`` (renames; the old ``out`` is deleted once the new one is there)."""
    if not out.exists():
        os.rename(stage, out)
        return
    old = set_aside(out)
    try:
        if old is None:  # an empty folder
            out.rmdir()
        os.rename(stage, out)
    except BaseException:  # interrupted before the new run is in place: the old one goes back
        if old is not None and not out.exists():
            os.rename(old / out.name, out)
            old.rmdir()
        raise
    if old is not None:
        try:
            shutil.rmtree(old, ignore_errors=True)
        except BaseException:  # interrupted: the new run is in place, and the old one is not left beside it
            shutil.rmtree(old, ignore_errors=True)
            raise


def write_continuous_outputs(result: Result, out: Path, animate: bool = False) -> list[Path]:
    """trajectories/robot_<i>.csv (uav_trajectories format) and the continuous figures."""
    from mrfswarm.trajectory import write_uav_csv

    c = result.smoothed()
    cfg = result.config
    written = []
    for i, tr in enumerate(c.trajectories):
        written.append(atomic_write(out / "trajectories" / f"robot_{i}.csv",
                                    partial(write_uav_csv, tr, altitude=cfg.scenario.altitude)))
    written += write_crazyflie_outputs(result, out)
    figs = out / "figures"
    grid = result.scenario.grid
    goal = result.scenario.goal_world
    t = np.linspace(0.0, c.makespan_s, max(2, int(c.makespan_s * 20) + 1))
    pos = c.positions(t)
    n = pos.shape[1]
    world = result.discrete_paths_world()
    # the NLP backend too where one refined the durations: a run per backend drew the same title (a solver tour)
    title = (f"smoothed trajectories ({cfg.smoothing.seam} seams, {result.smoothing_solvers}): makespan "
             f"{c.makespan_s:.1f} s")

    beneath = [world[:, i] for i in range(n)] if n <= plots.INDIVIDUAL_MAX else None  # the discrete paths
    written.append(atomic_write(figs / "trajectories.png", lambda p: plots.plot_paths(
        p, grid, [pos[:, i] for i in range(n)], goal, title, beneath=beneath, title_size=9)))
    from mrfswarm.geometry import downwash_scale
    from mrfswarm.metrics import distance_series

    # in the metric the separation is kept in: z divided by the downwash factor (a 2-D run's distances as they are)
    downwash = cfg.scenario.downwash if pos.shape[-1] == 3 else 1.0
    ds = distance_series(pos * downwash_scale(pos.shape[-1], downwash))
    safety = 2 * cfg.scenario.robot_radius
    ylabel = "distance [m]" if downwash == 1.0 else f"distance, z / {downwash:g} (downwash) [m]"
    written.append(atomic_write(figs / "distances.png", lambda p: plots.plot_distances(
        p, t, ds.min, ds.mean, safety, mean_pairs=None if ds.exact else ds.n_pairs, ylabel=ylabel,
        title="Inter-robot distance of the smooth trajectories")))
    axes = plots.AXES[:pos.shape[-1]]
    written.append(atomic_write(figs / f"robot_{axes}.png", lambda p: plots.plot_xy(p, t, pos)))
    f = result.flight
    if f is not None:
        err = np.stack([fl.tracking_error for fl in f.flights], axis=1)
        written.append(atomic_write(figs / "tracking_error.png", lambda p: plots.plot_tracking(
            p, f.flights[0].times, err, end=c.makespan_s)))
    if animate:
        frames = np.linspace(0.0, c.makespan_s, max(2, int(c.makespan_s * 5) + 1))  # 5 frames per flown second
        written.append(atomic_write(out / "animation.gif", lambda p: plots.animate(p, grid, frames, c.positions(frames),
                                                                                 goal, fps=10)))
    return written


#: Trajectory samples per second in the interactive view.
SCENE_RATE_HZ = 10


def write_scene(result: Result, out: Path) -> Path:
    """``figures/scene.html``: the interactive 3-D view (:mod:`mrfswarm.figures.interactive`) of the map, the
    discrete paths and, when the run has them, the trajectories."""
    from mrfswarm.figures.interactive import write_scene as write_html

    c = result.continuous
    t = pos = None
    if c is not None:
        t = np.linspace(0.0, c.makespan_s, max(2, int(c.makespan_s * SCENE_RATE_HZ) + 1))
        pos = c.positions(t)
    cfg = result.config
    title = f"{result.scenario.n_robots} robots, {result.mrf}: {result.discrete.n_steps} MRF steps" + (
        "" if c is None else f", makespan {c.makespan_s:.1f} s")
    return atomic_write(out / "figures" / "scene.html", lambda p: write_html(
        p, result.scenario.grid, result.discrete_paths_world(), pos, t, result.scenario.goal_world,
        cfg.scenario.altitude, title))


def write_crazyflie_outputs(result: Result, out: Path) -> list[Path]:
    """crazyswarm2/ (crazyflies.yaml, fly.py), crazyflie/ (cflib_upload.py and, when the flight fits the
    compressed format, compressed.json: the rounded pieces whose decoding ``result.json`` certifies)."""
    from mrfswarm.export.crazyswarm2 import blocked_columns, lowest_points, maneuvers, starts_of, write_crazyswarm2

    c = result.smoothed()
    starts = starts_of(c.trajectories)
    ends = np.array([tr.evaluate(tr.duration) for tr in c.trajectories])
    radius = result.config.scenario.robot_radius
    sm = result.config.smoothing
    lowest = columns = floor = None
    if starts.shape[-1] == 3:
        start_z, end_z = starts[:, 2], ends[:, 2]
    else:  # a 2-D plan flies at its altitude
        start_z = end_z = np.full(len(starts), result.config.scenario.altitude)
    maneuver = maneuvers(start_z, end_z, sm.v_max, sm.a_max, sm.j_max)
    if c.trajectories and c.trajectories[0].dim == 3:
        lowest = lowest_points(c.trajectories)
        grid = result.scenario.grid
        origin = np.asarray(grid.origin, dtype=float)
        floor = float(origin[2] - grid.resolution / 2)
        # the scripts take off to the highest start and land from each end
        columns = (blocked_columns(grid.occupied, origin, grid.resolution, starts[:, :2],
                                   np.full(len(starts), starts[:, 2].max()), radius),
                   blocked_columns(grid.occupied, origin, grid.resolution, ends[:, :2], ends[:, 2], radius))
    altitude = None if starts.shape[-1] == 3 else result.config.scenario.altitude
    written = write_crazyswarm2(starts, out, radius, lowest, columns, ends, maneuver, altitude, floor)
    _, comp = result._crazyflie_export()
    if comp is not None:
        written.append(write_json(out / "crazyflie" / "compressed.json", compressed_json(comp)))
    return written


def compressed_json(comp) -> dict:
    """The content of ``crazyflie/compressed.json`` (what ``cflib_upload.py --compressed`` uploads): the
    :class:`~mrfswarm.export.cflib_.Compressed` flight; ``z_mm`` is null for a 3-D flight (z in the points)."""
    return {"origin_m": [float(v) for v in comp.origin], "z_mm": comp.z_mm,
            "position_error_bound_m": comp.position_error_bound,
            "knots_ms": [k.tolist() for k in comp.knots_ms], "points_mm": [p.tolist() for p in comp.points_mm]}


def write_discrete_outputs(result: Result, out: Path) -> list[Path]:
    """discrete_paths.csv and the discrete figures into ``out`` (``result.json`` is :func:`write_outputs`'s, last)."""
    out = Path(out)
    figs = out / "figures"
    figs.mkdir(parents=True, exist_ok=True)
    world = result.discrete_paths_world()
    written = [write_discrete_csv(out / "discrete_paths.csv", world, result.config.scenario.altitude)]
    grid = result.scenario.grid
    goal = result.scenario.goal_world
    n = world.shape[1]
    paths = [world[:, i] for i in range(n)]
    pruned = [world[result.pruned[i], i] for i in range(n)]
    cfg = result.config
    title = f"{n} robots, k={cfg.interaction.k}, n={cfg.mrf.order}, {result.mrf}: {result.discrete.n_steps} MRF steps"
    written.append(atomic_write(figs / "discrete_paths.png", lambda p: plots.plot_paths(p, grid, paths, goal, title)))
    written.append(atomic_write(figs / "pruned_paths.png",
                                lambda p: plots.plot_paths(p, grid, pruned, goal, "pruned discrete paths (waypoints)",
                                                           waypoints=pruned)))
    written.append(atomic_write(figs / "swarm_energy.png",
                                lambda p: plots.plot_energy(p, {result.mrf: result.discrete.energy},
                                                            title=f"Swarm energy, MRF method {result.mrf}")))
    m = result.metrics
    written.append(atomic_write(figs / "discrete_distances.png", lambda p: plots.plot_distances(
        p, np.arange(len(m.mean_distance)), m.min_distance, m.mean_distance, xlabel="MRF step",
        mean_pairs=m.mean_distance_pairs, safety=float(grid.resolution), safety_label="one cell ({:g} m): the least",
        title="Inter-robot distance of the discrete plan, per MRF step")))
    return written
