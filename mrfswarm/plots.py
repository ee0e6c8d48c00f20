"""Figures in the paper's style: paths over the map, energy per step, distances over time.

matplotlib is imported here only (Agg backend); every function writes one PNG and
returns its path. Obstacles are grey, start positions green, end positions blue, as in
the paper's Fig. 6.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from mrfswarm.maps import OccupancyGrid


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _robot_colors(n: int):
    plt = _plt()
    cmap = plt.get_cmap("tab10" if n <= 10 else "turbo")
    return [cmap(i % 10) if n <= 10 else cmap(i / max(1, n - 1)) for i in range(n)]


def draw_map(ax, grid: OccupancyGrid) -> None:
    """Obstacles in grey on white, world coordinates, equal aspect."""
    x0, x1, y0, y1 = grid.extent
    ax.imshow(np.where(grid.occupied, 0.55, 1.0).T, origin="lower", extent=(x0, x1, y0, y1), cmap="gray",
              vmin=0, vmax=1, interpolation="nearest")
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")


def draw_paths(ax, grid: OccupancyGrid, paths_world: Sequence[np.ndarray], goal: np.ndarray | None = None,
               markers: bool = True, lw: float = 1.4, waypoints: Sequence[np.ndarray] | None = None) -> None:
    """Each robot's path (an (T, 2) array in metres) with start (green) and end (blue) markers."""
    colors = _robot_colors(len(paths_world))
    for i, p in enumerate(paths_world):
        ax.plot(p[:, 0], p[:, 1], "-", color=colors[i], lw=lw, alpha=0.9)
        if waypoints is not None:
            w = waypoints[i]
            ax.plot(w[:, 0], w[:, 1], "o", ms=3, mfc="white", mec=colors[i], mew=1.0)
    if markers and len(paths_world):
        starts = np.array([p[0] for p in paths_world])
        ends = np.array([p[-1] for p in paths_world])
        ax.plot(starts[:, 0], starts[:, 1], "o", ms=7, color="tab:green", mec="k", mew=0.6, label="start", zorder=5)
        ax.plot(ends[:, 0], ends[:, 1], "o", ms=7, color="tab:blue", mec="k", mew=0.6, label="end", zorder=5)
    if goal is not None:
        ax.plot(goal[0], goal[1], "*", ms=16, color="gold", mec="k", label="goal", zorder=6)


def plot_paths(path: Path, grid: OccupancyGrid, paths_world: Sequence[np.ndarray], goal: np.ndarray | None = None,
               title: str = "", waypoints: Sequence[np.ndarray] | None = None) -> Path:
    """Paths over the map (the paper's Fig. 6 panels)."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6, 6), dpi=110)
    draw_map(ax, grid)
    draw_paths(ax, grid, paths_world, goal, waypoints=waypoints)
    ax.legend(loc="upper left", fontsize=8, framealpha=0.9)
    ax.set_title(title)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return Path(path)


def plot_energy(path: Path, energies: dict[str, np.ndarray], title: str = "Swarm energy") -> Path:
    """Swarm energy per MRF step, one line per series (the paper's Fig. 8a)."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6, 4), dpi=110)
    for name, e in energies.items():
        ax.plot(np.arange(len(e)), e, "-o", ms=3, label=name)
    ax.set_xlabel("MRF step")
    ax.set_ylabel("swarm energy")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    if len(energies) > 1:
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return Path(path)


def plot_distances(path: Path, t: np.ndarray, min_d: np.ndarray, mean_d: np.ndarray, safety: float | None = None,
                   xlabel: str = "time [s]") -> Path:
    """Minimum and average inter-robot distance over time (the paper's Fig. 7c)."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7, 3.5), dpi=110)
    ax.plot(t, mean_d, label="average distance")
    ax.plot(t, min_d, label="minimum distance")
    if safety is not None:
        ax.axhline(safety, color="r", ls="--", lw=1, label=f"safety distance {safety:g} m")
    ax.set_xlabel(xlabel)
    ax.set_ylabel("distance [m]")
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return Path(path)
