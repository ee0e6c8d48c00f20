"""Writing a run's outputs: ``result.json``, ``discrete_paths.csv``, figures.

Every file is written to a temporary name and renamed, so a run that fails half-way
never leaves a truncated file; what was computed before the failure is still written.
"""

from __future__ import annotations

import json
import os
import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np

from mrfswarm import plots
from mrfswarm.pipeline import Result


def atomic_write(path: Path, write: Callable[[Path], None]) -> Path:
    """Call ``write(tmp)`` then rename ``tmp`` to ``path`` (same folder, same suffix)."""
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
            for s, r, (x, y) in zip(steps, robots, xy):
                f.write(f"{s},{r},{x:.6g},{y:.6g}\n")

    return atomic_write(path, write)


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
        p, np.arange(len(m.mean_distance)), m.min_distance, m.mean_distance, xlabel="MRF step")))
    return written
