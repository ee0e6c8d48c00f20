"""Figs. 3 and 4: the interaction potential map, the obstacle map and its smoothed field,
and the combined potential field.

- Fig. 3b: rho_I summed over the 5 example robots, as the energy a robot at p would add:
  I(p) = sum_j rho_I(|p - x_j|). Its valley is the ring where a sixth robot would sit
  best; it lies around d_min (8.4 m with the paper's parameters) from the robots, so the
  field is drawn on a window larger than the robots' 10 x 10 grid (outlined).
- Fig. 3c/d: m_hat (Gamma on occupied cells) and rho_O = m_hat convolved with a Gaussian
  of sigma_hat, on the blocks scenario's map (the authors' geometry).
- Fig. 4: rho_S + I over ``experiments/combined_field.toml`` (goal at (65, 15), as in
  the paper's text; the map is ours).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mrfswarm import plots
from mrfswarm.discrete.potentials import Morse, obstacle_field
from mrfswarm.figures.runs import experiment_config
from mrfswarm.maps import OccupancyGrid
from mrfswarm.scenario import build_scenario

#: The scenario whose map Fig. 3c/d show.
OBSTACLE_MAP = "blocks"
#: The scenario of Fig. 4.
COMBINED = "combined_field"
#: Extra metres drawn around the example's 10 x 10 grid in Fig. 3b.
INTERACTION_MARGIN = 10.0
#: Sample spacing (m) of the interaction map.
INTERACTION_STEP = 0.25


def interaction_field(points: np.ndarray, robots: np.ndarray, morse: Morse) -> np.ndarray:
    """I(p) = sum_j rho_I(|p - x_j|) at each point of ``points`` (..., 2), metres."""
    d = np.linalg.norm(np.asarray(points, float)[..., None, :] - np.asarray(robots, float), axis=-1)
    return np.asarray(morse(d)).sum(axis=-1)


@dataclass(frozen=True)
class InteractionMap:
    """The numbers behind Fig. 3b.

    Attributes
    ----------
    xs, ys
        Sample coordinates (m) of the field's columns and rows.
    field
        (len(xs), len(ys)) I(p).
    robots
        (N, 2) robot positions (m).
    morse
        The interaction potential.
    """

    xs: np.ndarray
    ys: np.ndarray
    field: np.ndarray
    robots: np.ndarray
    morse: Morse

    @property
    def extent(self) -> tuple[float, float, float, float]:
        h = (self.xs[1] - self.xs[0]) / 2
        return (self.xs[0] - h, self.xs[-1] + h, self.ys[0] - h, self.ys[-1] + h)

    def minimum(self) -> tuple[np.ndarray, float]:
        """Where the field is lowest (m) and its value."""
        i, j = np.unravel_index(np.argmin(self.field), self.field.shape)
        return np.array([self.xs[i], self.ys[j]]), float(self.field[i, j])

    def radial_profile(self, bins: np.ndarray) -> np.ndarray:
        """Minimum of the field over rings of distance from the robots' centroid (one per bin)."""
        c = self.robots.mean(axis=0)
        X, Y = np.meshgrid(self.xs, self.ys, indexing="ij")
        r = np.hypot(X - c[0], Y - c[1])
        idx = np.digitize(r, bins) - 1
        return np.array([self.field[idx == b].min() if np.any(idx == b) else np.nan for b in range(len(bins) - 1)])


def interaction_map(margin: float = INTERACTION_MARGIN, step: float = INTERACTION_STEP) -> InteractionMap:
    """I(p) around the 5 example robots (Fig. 3b)."""
    from mrfswarm.figures.graphs import example_scenario

    scn = example_scenario()
    robots = scn.grid.cell_to_world(scn.start)
    x0, x1, y0, y1 = scn.grid.extent
    xs = np.arange(x0 - margin + step / 2, x1 + margin, step)
    ys = np.arange(y0 - margin + step / 2, y1 + margin, step)
    P = np.stack(np.meshgrid(xs, ys, indexing="ij"), axis=-1)
    return InteractionMap(xs=xs, ys=ys, field=interaction_field(P, robots, scn.morse), robots=robots,
                          morse=scn.morse)


@dataclass(frozen=True)
class ObstacleMaps:
    """The numbers behind Fig. 3c/d: m_hat and rho_O over a map (arrays indexed [ix, iy])."""

    grid: OccupancyGrid
    m_hat: np.ndarray
    rho_o: np.ndarray
    gamma: float
    sigma: float


def obstacle_maps(name: str = OBSTACLE_MAP) -> ObstacleMaps:
    """m_hat (no blur) and rho_O (blurred with sigma_hat) of a scenario's map."""
    import dataclasses

    cfg = experiment_config(name)
    grid = build_scenario(cfg).grid
    oc = cfg.obstacle_potential
    m_hat = obstacle_field(grid.prob, dataclasses.replace(oc, sigma=0.0))
    return ObstacleMaps(grid=grid, m_hat=m_hat, rho_o=obstacle_field(grid.prob, oc), gamma=oc.gamma, sigma=oc.sigma)


@dataclass(frozen=True)
class CombinedField:
    """The numbers behind Fig. 4 (arrays indexed [ix, iy], one value per cell).

    Attributes
    ----------
    grid
        The map.
    static
        rho_S = rho_G + rho_O.
    interaction
        I(cell) of the robots at their start cells.
    robots, goal
        Robot positions and goal (m).
    """

    grid: OccupancyGrid
    static: np.ndarray
    interaction: np.ndarray
    robots: np.ndarray
    goal: np.ndarray

    @property
    def field(self) -> np.ndarray:
        return self.static + self.interaction

    def argmin(self) -> np.ndarray:
        """World position (m) of the field's lowest cell."""
        return self.grid.cell_to_world(np.array(np.unravel_index(np.argmin(self.field), self.field.shape)))


def combined_field(name: str = COMBINED) -> CombinedField:
    """rho_S + I over the map of ``experiments/<name>.toml``, robots at their start."""
    scn = build_scenario(experiment_config(name))
    W, H = scn.grid.shape
    cells = np.stack(np.meshgrid(np.arange(W), np.arange(H), indexing="ij"), axis=-1)
    world = scn.grid.cell_to_world(cells.reshape(-1, 2)).reshape(W, H, 2)
    robots = scn.grid.cell_to_world(scn.start)
    assert scn.goal_world is not None  # the combined-field scenario has a goal
    return CombinedField(grid=scn.grid, static=scn.static, interaction=interaction_field(world, robots, scn.morse),
                         robots=robots, goal=scn.goal_world)


def make_fig3(out: Path, quick: bool = False) -> list[Path]:
    """Write ``fig3_potentials.png``: (a) robots, (b) interaction map, (c) m_hat, (d) rho_O."""
    from mrfswarm.figures.graphs import draw_grid_robots, example_graph

    g = example_graph()
    im = interaction_map()
    om = obstacle_maps()
    plt = plots._plt()
    with plots.paper_style():
        fig, axes = plt.subplots(1, 4, figsize=(17, 4.6), layout="constrained",
                                 gridspec_kw={"width_ratios": [0.8, 1, 1, 1]})
        draw_grid_robots(axes[0], g, edges=False)
        plots.panel_title(axes[0], "a", "5 interacting robots")
        ax = axes[1]
        plots.draw_field(ax, im.field, im.extent, label=r"$\Sigma_j\,\rho_I(|p - x_j|)$", cmap="viridis", contours=12)
        ax.add_patch(plt.Rectangle((-0.5, -0.5), 10, 10, fill=False, ec="w", ls="--", lw=1.0))
        ax.scatter(im.robots[:, 0], im.robots[:, 1], s=40, c="tab:red", edgecolors="w", zorder=5, label="robots")
        p, v = im.minimum()
        ax.plot(p[0], p[1], "x", color="w", ms=9, mew=2, label=f"minimum {v:.2f}")
        ax.legend(loc="lower left", fontsize=8, framealpha=0.8)
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        plots.panel_title(ax, "b", f"interaction potential (valley ~{im.morse.d_min:.1f} m out)")
        ext = om.grid.extent
        plots.draw_field(axes[2], om.m_hat, ext, label=r"$\hat m$", cmap="Greys", vmin=0, vmax=om.gamma)
        plots.panel_title(axes[2], "c", rf"obstacle map $\hat m$ ($\Gamma$ = {om.gamma:g})")
        plots.draw_field(axes[3], om.rho_o, ext, label=r"$\rho_O$", cmap="magma", vmin=0, vmax=om.gamma)
        plots.panel_title(axes[3], "d", rf"smoothed obstacle potential ($\hat\sigma$ = {om.sigma:g})")
        for ax in axes[2:]:
            ax.set_xlabel("x [m]")
            ax.set_ylabel("y [m]")
        fig.suptitle("Fig. 3: interaction potential of 5 robots (a, b) and obstacle potential of the blocks map (c, d)")
        return [plots.save_figure(fig, Path(out) / "fig3_potentials.png")]


def make_fig4(out: Path, quick: bool = False) -> list[Path]:
    """Write ``fig4_combined_field.png``: a 3-D surface and a top view (log colour scale) of rho_S + I."""
    from matplotlib.colors import LogNorm
    from mpl_toolkits.mplot3d.art3d import Line3DCollection

    cf = combined_field()
    plt = plots._plt()
    F = cf.field
    W, H = F.shape
    with plots.paper_style():
        fig = plt.figure(figsize=(12, 9.6))
        ax3 = fig.add_axes([-0.06, 0.36, 1.1, 0.64], projection="3d")
        X, Y = np.meshgrid(np.arange(W), np.arange(H), indexing="ij")
        XY = cf.grid.cell_to_world(np.stack([X, Y], axis=-1).reshape(-1, 2)).reshape(W, H, 2)
        norm = LogNorm(vmin=F.min(), vmax=F.max())
        ax3.plot_surface(XY[..., 0], XY[..., 1], F, facecolors=plt.get_cmap("viridis")(norm(F)), rstride=1,
                         cstride=1, linewidth=0, antialiased=False, shade=False)
        # the obstacles' outline on the surface, at the field's height at each cell corner (the mean of the cells
        # around it), drawn over the surface: their bumps alone are faint (they add up to 5 on a field of ~30)
        corners = np.pad(F, 1, mode="edge")
        corners = (corners[:-1, :-1] + corners[1:, :-1] + corners[:-1, 1:] + corners[1:, 1:]) / 4
        edges = plots.obstacle_edges(cf.grid)
        ij = np.rint((edges - np.asarray(cf.grid.origin)) / cf.grid.resolution + 0.5).astype(int)
        ax3.computed_zorder = False
        ax3.add_collection3d(Line3DCollection(np.concatenate([edges, corners[ij[..., 0], ij[..., 1]][..., None]], -1),
                                              colors="k", linewidths=1.5, zorder=3))
        ax3.set_box_aspect((W / H, 1, 1.0), zoom=1.25)
        ax3.view_init(elev=38, azim=-75)
        ax3.set_xlabel("x [m]", labelpad=8)
        ax3.set_ylabel("y [m]")
        ax3.set_zlabel("energy")
        ax3.set_title("combined potential field $\\rho_G + \\rho_O + \\Sigma_j\\,\\rho_I$ (3-D view; obstacles "
                      "outlined)", y=0.93)
        ax = fig.add_axes([0.07, 0.05, 0.86, 0.32])
        plots.draw_field(ax, F, cf.grid.extent, label="energy (log scale)", cmap="viridis", norm=norm)
        xs = cf.grid.cell_to_world(np.stack([np.arange(W), np.zeros(W, int)], 1))[:, 0]
        ys = cf.grid.cell_to_world(np.stack([np.zeros(H, int), np.arange(H)], 1))[:, 1]
        ax.contour(xs, ys, F.T, levels=np.geomspace(F.min() * 1.02, F.max(), 22), colors="w", linewidths=0.5,
                   alpha=0.6)
        plots.outline_obstacles(ax, cf.grid)
        ax.plot([], [], color="k", lw=1.5, label="obstacles (occupied cells)")
        ax.scatter(cf.robots[:, 0], cf.robots[:, 1], s=30, c="tab:red", edgecolors="w", zorder=5, label="robots")
        ax.plot(cf.goal[0], cf.goal[1], "*", ms=15, color="gold", mec="k", zorder=6,
                label=f"goal ({cf.goal[0]:g}, {cf.goal[1]:g})")
        ax.legend(loc="upper left", fontsize=8.5, framealpha=0.85)
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        start = F[tuple(cf.grid.world_to_cell(cf.robots.mean(axis=0)))]
        ax.set_title(f"top view: valley at the goal ({F.min():.1f}); obstacles add up to 5; the robots' interaction "
                     f"adds {cf.interaction.min():.2f}-{cf.interaction.max():.2f} to ~{start:.0f} at their start")
        fig.suptitle("Fig. 4: combined potential field on our 80 x 30 m map, goal at (65, 15) as in the paper",
                     y=0.995)
        return [plots.save_figure(fig, Path(out) / "fig4_combined_field.png")]


def numbers_fig3(quick: bool = False) -> dict:
    """The numbers behind Fig. 3, for ``measured.json``."""
    im = interaction_map()
    p, v = im.minimum()
    c = im.robots.mean(axis=0)
    om = obstacle_maps()
    return {
        "d_min_m": im.morse.d_min,
        "zeta": im.morse.zeta,
        "interaction_min_at_m": p.tolist(),
        "interaction_min_distance_from_centroid_m": float(np.hypot(*(p - c))),
        "interaction_min": v,
        "interaction_at_centroid": float(interaction_field(c, im.robots, im.morse)),
        "m_hat_values": sorted(set(np.unique(om.m_hat).tolist())),
        "rho_o_max": float(om.rho_o.max()),
        "rho_o_zero_fraction": float(np.mean(om.rho_o == 0)),
    }


def numbers_fig4(quick: bool = False) -> dict:
    """The numbers behind Fig. 4, for ``measured.json``."""
    cf = combined_field()
    start = cf.grid.world_to_cell(cf.robots.mean(axis=0))
    return {
        "goal_m": cf.goal.tolist(),
        "argmin_m": cf.argmin().tolist(),
        "field_at_goal": float(cf.field[tuple(cf.grid.world_to_cell(cf.goal))]),
        "field_at_start_centroid": float(cf.field[tuple(start)]),
        "field_max": float(cf.field.max()),
        "interaction_range": [float(cf.interaction.min()), float(cf.interaction.max())],
    }
