"""Writing a run's outputs: ``result.json``, ``discrete_paths.csv``, figures.

Every file is written to a temporary name and renamed, so a run that fails half-way
never leaves a truncated file; what was computed before the failure is still written.
"""

from __future__ import annotations

import json
import os
import tempfile
from collections.abc import Callable
from functools import partial
from pathlib import Path

import numpy as np

from mrfswarm import plots
from mrfswarm.pipeline import Result


def atomic_write(path: Path, write: Callable[[Path], object]) -> Path:
    """Call ``write(tmp)`` (its return value is ignored) then rename ``tmp`` to ``path`` (same folder, same suffix)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.stem}.", suffix=path.suffix)
    os.close(fd)
    try:
        write(Path(tmp))
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def write_json(path: Path, data: dict) -> Path:
    return atomic_write(path, lambda p: p.write_text(json.dumps(data, indent=2) + "\n"))


def write_discrete_csv(path: Path, paths_world: np.ndarray) -> Path:
    """``step,robot,x,y`` in metres, one row per robot per step."""
    T1, N, _ = paths_world.shape
    steps = np.repeat(np.arange(T1), N)
    robots = np.tile(np.arange(N), T1)
    xy = paths_world.reshape(-1, 2)

    def write(p: Path) -> None:
        with open(p, "w") as f:
            f.write("step,robot,x,y\n")
            for a in range(0, len(xy), 100_000):  # one formatting call per block of rows
                b = a + 100_000
                rows = zip(steps[a:b].tolist(), robots[a:b].tolist(), xy[a:b, 0].tolist(), xy[a:b, 1].tolist())
                f.write("".join(f"{s},{r},{x:.6g},{y:.6g}\n" for s, r, x, y in rows))

    return atomic_write(path, write)


def write_outputs(result: Result, out: Path, animate: bool = False) -> list[Path]:
    """Everything a run computed: discrete outputs, trajectories, continuous figures, GIF."""
    written = write_discrete_outputs(result, out)
    if result.continuous is not None:
        written += write_continuous_outputs(result, Path(out), animate)
    return written


def write_continuous_outputs(result: Result, out: Path, animate: bool = False) -> list[Path]:
    """trajectories/robot_<i>.csv (uav_trajectories format) and the continuous figures."""
    from mrfswarm.trajectory import write_uav_csv

    c = result.smoothed()
    cfg = result.config
    written = []
    for i, tr in enumerate(c.trajectories):
        written.append(atomic_write(out / "trajectories" / f"robot_{i}.csv",
                                    partial(write_uav_csv, tr, altitude=cfg.scenario.altitude)))
    figs = out / "figures"
    grid = result.scenario.grid
    goal = result.scenario.goal_world
    t = np.linspace(0.0, c.makespan_s, max(2, int(c.makespan_s * 20) + 1))
    pos = c.positions(t)
    n = pos.shape[1]
    world = result.discrete_paths_world()
    title = f"smoothed trajectories ({cfg.smoothing.seam} seams, {result.qp}): makespan {c.makespan_s:.1f} s"

    def traj_fig(p: Path) -> None:
        plt = plots._plt()
        fig, ax = plt.subplots(figsize=(6, 6), dpi=110)
        plots.draw_map(ax, grid)
        if n <= plots.INDIVIDUAL_MAX:  # the discrete paths beneath the smooth ones
            plots._lines(ax, [world[:, i] for i in range(n)], "0.5", lw=0.8, ls=":")
        plots.draw_paths(ax, grid, [pos[:, i] for i in range(n)], goal)
        ax.legend(loc="upper left", fontsize=8, framealpha=0.9)
        ax.set_title(title, fontsize=9)
        fig.tight_layout()
        plots.save_figure(fig, p, dpi=110)

    written.append(atomic_write(figs / "trajectories.png", traj_fig))
    from mrfswarm.metrics import distance_series

    ds = distance_series(pos)
    safety = 2 * cfg.scenario.robot_radius
    written.append(atomic_write(figs / "distances.png", lambda p: plots.plot_distances(
        p, t, ds.min, ds.mean, safety, mean_pairs=None if ds.exact else ds.n_pairs)))
    written.append(atomic_write(figs / "robot_xy.png", lambda p: plots.plot_xy(p, t, pos)))
    f = result.flight
    if f is not None:
        err = np.stack([fl.tracking_error for fl in f.flights], axis=1)
        written.append(atomic_write(figs / "tracking_error.png", lambda p: plots.plot_tracking(p, f.flights[0].times, err)))
    if animate:
        frames = np.linspace(0.0, c.makespan_s, max(2, int(c.makespan_s * 5) + 1))  # 5 frames per flown second
        written.append(atomic_write(out / "animation.gif", lambda p: plots.animate(p, grid, frames, c.positions(frames),
                                                                                 goal, fps=10)))
    return written


def write_discrete_outputs(result: Result, out: Path) -> list[Path]:
    """result.json, discrete_paths.csv and the discrete figures into ``out``."""
    out = Path(out)
    figs = out / "figures"
    figs.mkdir(parents=True, exist_ok=True)
    world = result.discrete_paths_world()
    written = [write_json(out / "result.json", result.summary()), write_discrete_csv(out / "discrete_paths.csv", world)]
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
                                lambda p: plots.plot_energy(p, {result.mrf: result.discrete.energy})))
    m = result.metrics
    written.append(atomic_write(figs / "discrete_distances.png", lambda p: plots.plot_distances(
        p, np.arange(len(m.mean_distance)), m.min_distance, m.mean_distance, xlabel="MRF step",
        mean_pairs=m.mean_distance_pairs)))
    return written
