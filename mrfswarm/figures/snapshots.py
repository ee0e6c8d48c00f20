"""Fig. 5: MRF optimization steps for 5 robots passing a single obstacle.

(a) the start, (b)(c)(d) the swarm after 4, 7 and 14 MRF steps (each with its k-NN
interaction graph and the paths so far), (e) the discrete paths after waypoint pruning
per planning horizon (the paper's H = 4 steps). The scenario is
``experiments/single_obstacle.toml`` (the paper does not give its geometry).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mrfswarm import plots
from mrfswarm.discrete.interaction_graph import knn_edges
from mrfswarm.figures.runs import discrete_run
from mrfswarm.metrics import obstacle_clearance
from mrfswarm.pipeline import Result

#: The scenario of Fig. 5.
SCENARIO = "single_obstacle"
#: The paper's snapshot steps.
SNAPSHOT_STEPS = (0, 4, 7, 14)
#: The paper's planning horizon for the waypoint pruning ("4 local optimization steps as the planning
#: horizon for both waypoint pruning and RHP"); the config's default, 8, is our continuous stage's.
PRUNING_HORIZON = 4


@dataclass(frozen=True)
class Snapshots:
    """The numbers behind Fig. 5.

    Attributes
    ----------
    result
        The discrete run (paths, energies, pruning per planning horizon).
    steps
        The snapshot steps (clipped to the run's length).
    """

    result: Result

    @property
    def steps(self) -> tuple[int, ...]:
        return tuple(min(s, self.result.discrete.n_steps) for s in SNAPSHOT_STEPS)

    @property
    def world(self) -> np.ndarray:
        """(T + 1, N, 2) discrete paths in metres."""
        return self.result.discrete_paths_world()

    def pruned_world(self) -> list[np.ndarray]:
        """Per robot, its kept waypoints (m)."""
        w = self.world
        return [w[k, i] for i, k in enumerate(self.result.pruned)]

    def waypoints(self) -> tuple[int, int]:
        """(waypoints before pruning, after) summed over the robots."""
        n = self.world.shape[1]
        return n * len(self.world), int(sum(len(k) for k in self.result.pruned))

    def pruned_clearance(self) -> float | None:
        """Smallest distance (m) from the pruned polylines to an obstacle."""
        g = self.result.scenario.grid
        pts = []
        for i, k in enumerate(self.result.pruned):
            cells = self.result.discrete.paths[k, i].astype(float)
            s = np.linspace(0, 1, 33)[:, None, None]
            pts.append((cells[:-1][None] + s * (cells[1:] - cells[:-1])[None]).reshape(-1, 2))
        c = obstacle_clearance(g.occupied, np.concatenate(pts))
        return None if c is None else c * g.resolution


def mrf_snapshots() -> Snapshots:
    """Plan the single-obstacle scenario (discrete stage and the paper's pruning)."""
    return Snapshots(result=discrete_run(SCENARIO, (f"smoothing.horizon={PRUNING_HORIZON}",)))


def make_fig5(out: Path, quick: bool = False) -> list[Path]:
    """Write ``fig5_mrf_steps.png``."""
    snap = mrf_snapshots()
    r = snap.result
    grid = r.scenario.grid
    goal = r.scenario.goal_world
    assert goal is not None  # the scenario has a goal
    world = snap.world
    k = r.config.interaction.k
    n = world.shape[1]
    colors = plots._robot_colors(n)
    plt = plots._plt()
    with plots.paper_style():
        fig, grid_axes = plt.subplots(2, 3, figsize=(15.5, 7.4), layout="constrained")
        axes = grid_axes.ravel()
        for ax, letter, t in zip(axes, "abcd", snap.steps):
            plots.draw_map(ax, grid)
            for i in range(n):
                ax.plot(world[:t + 1, i, 0], world[:t + 1, i, 1], "-", color=colors[i], lw=1.0, alpha=0.6)
            plots.draw_graph(ax, world[t], knn_edges(world[t], k), node_size=130, color=colors)
            ax.plot(goal[0], goal[1], "*", ms=14, color="gold", mec="k", zorder=6)
            e = r.discrete.energy[t]
            plots.panel_title(ax, letter, "initial robots" if t == 0 else f"after {t} MRF steps")
            ax.text(0.02, 0.03, f"swarm energy {e:.1f}", transform=ax.transAxes, fontsize=8.5,
                    bbox={"fc": "w", "ec": "0.7", "alpha": 0.85})
        ax = axes[4]
        plots.draw_map(ax, grid)
        for i in range(n):
            ax.plot(world[:, i, 0], world[:, i, 1], ":", color="0.55", lw=0.9)
        plots.draw_paths(ax, grid, snap.pruned_world(), goal, waypoints=snap.pruned_world(), lw=1.6)
        before, after = snap.waypoints()
        plots.panel_title(ax, "e", f"pruned per {PRUNING_HORIZON} steps ({after} of {before} waypoints)")
        ax.legend(loc="upper left", fontsize=7.5, framealpha=0.9)
        x0, x1, y0, y1 = grid.extent
        lo = max(y0, world[..., 1].min() - 3.5)
        hi = min(y1, world[..., 1].max() + 3.5)
        for ax in axes[:5]:
            ax.set_ylim(lo, hi)
        ax = axes[5]
        e = r.discrete.energy
        ax.plot(np.arange(len(e)), e, "-o", ms=3, color="0.3", label="swarm energy")
        ax.plot(snap.steps, e[list(snap.steps)], "o", ms=8, mfc="none", mec="tab:red", mew=1.6,
                label="snapshots (a)-(d)")
        ax.set_xlabel("MRF step")
        ax.set_ylabel("swarm energy")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8.5)
        plots.panel_title(ax, "f", "swarm energy per step (not in the paper)")
        fig.suptitle(f"Fig. 5: MRF optimization of {n} robots (k = {k}, n = {r.config.mrf.order}, ICM) passing one "
                     f"obstacle; {r.discrete.n_steps} steps to converge; dotted: unpruned discrete paths")
        return [plots.save_figure(fig, Path(out) / "fig5_mrf_steps.png")]


def numbers_fig5(quick: bool = False) -> dict:
    """The numbers behind Fig. 5, for ``measured.json``."""
    snap = mrf_snapshots()
    r = snap.result
    before, after = snap.waypoints()
    return {
        "mrf_steps": r.discrete.n_steps,
        "stop_reason": r.discrete.stop_reason,
        "reached_goal": r.metrics.reached_goal,
        "final_goal_distance_m": r.metrics.final_goal_distance,
        "min_separation_m": r.metrics.min_separation,
        "min_obstacle_clearance_m": r.metrics.min_obstacle_clearance,
        "waypoints_before_pruning": before,
        "waypoints_after_pruning": after,
        "pruned_min_obstacle_clearance_m": snap.pruned_clearance(),
        "swarm_energy_at_snapshots": {int(t): float(r.discrete.energy[t]) for t in snap.steps},
    }
