"""Figs. 1 and 6, the animations, and the trajectory numbers behind Figs. 7a and 7c.

- Fig. 6 (a)-(d): final discrete trajectories of free5, free10, corridor and blocks;
  (e)(f): free5 and free10 smoothed in one min-snap window ("optimized trajectories");
  (g)(h): corridor and blocks smoothed in the receding horizon (ours: safe regions,
  continuous seams). ``fig6_seams``: the corridor flown three ways, the paper's
  receding horizon (4 steps planned, 50 % executed, at rest at the seams: its
  "stop-start" sharp edges), ours, and ours with refined step durations.
- Fig. 1: the blocks flight in 3-D (the paper's is a Gazebo render; ours draws the
  smoothed trajectories at the flight altitude among the blocks).
- Fig. 7a/7c numbers: robot positions and the minimum and average inter-robot
  distances over time in the corridor (receding horizon).
- The free-space formation census: the shape 5 robots settle into, over seeds.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache
from pathlib import Path

import numpy as np
from scipy.spatial import ConvexHull
from scipy.spatial.distance import pdist, squareform

from mrfswarm import plots
from mrfswarm.config import Config
from mrfswarm.figures.runs import SCENARIOS, discrete_run, scenario_run
from mrfswarm.metrics import distance_series
from mrfswarm.pipeline import Result

#: How each scenario is smoothed in Fig. 6 (e)-(h) (a key of ``runs.SMOOTHING``).
SMOOTHED = {"free5": "single", "free10": "single", "corridor": "default", "blocks": "default"}
#: The corridor's continuous-stage variants of ``fig6_seams``.
VARIANTS = ("paper", "default", "refined")
#: The cruise speed of Fig. 7's time series (the earlier default), to compare with the paper's time axis.
PAPER_PACE = ("smoothing.speed=1.25",)
#: Samples per second of flight for the time series.
RATE_HZ = 20.0
#: Seeds of the formation census.
CENSUS_SEEDS = 20


def smoothed_run(name: str) -> Result:
    """The run of Fig. 6 (e)-(h) for a scenario (its discrete stage gives (a)-(d))."""
    return scenario_run(name, SMOOTHED[name])


@dataclass(frozen=True)
class TimeSeries:
    """Positions of every robot over time, and their separation.

    Attributes
    ----------
    t
        (S,) seconds.
    positions
        (S, N, 2) metres.
    min_distance, mean_distance
        (S,) smallest and average inter-robot distance.
    safety
        The configured safety distance (m).
    """

    t: np.ndarray
    positions: np.ndarray
    min_distance: np.ndarray
    mean_distance: np.ndarray
    safety: float

    def expansion(self, window_s: float = 10.0) -> dict:
        """The initial expansion: when the average distance first rises and peaks.

        Returns the average distance at t = 0, its first maximum within ``window_s``
        (value and time), and the interval over which it rises to that maximum (from the
        first sample 1 % above the start to the first sample within 1 % of the peak).
        """
        m = self.mean_distance
        sel = self.t <= window_s
        k = int(np.argmax(m[sel]))
        peak = float(m[k])
        rising = np.flatnonzero(m[: k + 1] > m[0] * 1.01)
        near = np.flatnonzero(m[: k + 1] >= m[0] + 0.99 * (peak - m[0]))
        return {
            "start_m": float(m[0]),
            "peak_m": peak,
            "rise_m": peak - float(m[0]),
            "rise_from_s": float(self.t[rising[0]]) if len(rising) else None,
            "peak_reached_s": float(self.t[near[0]]) if len(near) else None,
            "peak_held_until_s": float(self.t[k + np.argmax(m[k:] < peak - 0.05)]) if np.any(m[k:] < peak - 0.05)
            else float(self.t[-1]),
        }

    def speeds(self) -> np.ndarray:
        """(S - 1, N) speed of each robot between samples."""
        return np.linalg.norm(np.diff(self.positions, axis=0), axis=-1) / np.diff(self.t)[:, None]

    def stops(self) -> np.ndarray:
        """Per robot, how many times it comes to rest and starts again inside its flight
        (:func:`mrfswarm.flight_quality.stops_in_speeds`, the benchmarks' count)."""
        from mrfswarm.flight_quality import stops_in_speeds

        return stops_in_speeds(self.speeds())


def time_series(name: str, rate_hz: float = RATE_HZ, smoothing: str | None = None,
                overrides: tuple[str, ...] = ()) -> TimeSeries:
    """The smoothed flight of a scenario sampled at ``rate_hz`` (Fig. 6's smoothing unless given)."""
    r = scenario_run(name, smoothing or SMOOTHED[name], overrides)
    c = r.smoothed()
    t = np.linspace(0.0, c.makespan_s, int(c.makespan_s * rate_hz) + 1)
    pos = c.positions(t)
    ds = distance_series(pos)
    return TimeSeries(t=t, positions=pos, min_distance=ds.min, mean_distance=ds.mean,
                      safety=2 * r.config.scenario.robot_radius)


def corridor_series() -> TimeSeries:
    """The corridor flight (Figs. 7a and 7c), at the 1.25 m/s cruise of the earlier default.

    The paper's time axis: its swarm expands in the corridor between 2 and 4 s. The default
    time grid (from the limits) flies the corridor about a third faster, and the
    expansion then starts sooner and peaks lower (0.45 m).
    """
    return time_series("corridor", overrides=PAPER_PACE)


def formation_shape(points: np.ndarray) -> str:
    """``pentagon`` (5 robots on their convex hull), ``centred square`` (4 on it, 1 inside) or ``other``."""
    p = np.asarray(points, dtype=float)
    if len(p) != 5:
        return "other"
    hull = len(ConvexHull(p).vertices)
    return {5: "pentagon", 4: "centred square"}.get(hull, "other")


def nearest_distances(points: np.ndarray) -> np.ndarray:
    """Each robot's distance to its nearest neighbour."""
    D = squareform(pdist(np.asarray(points, dtype=float)))
    np.fill_diagonal(D, np.inf)
    return D.min(axis=1)


@cache
def formation_census(seeds: int = CENSUS_SEEDS) -> dict:
    """The shapes free5's swarm converges to over start seeds 0..seeds-1, and its steps."""
    shapes, steps = [], []
    for s in range(seeds):
        r = discrete_run("free5", seed=s)
        shapes.append(formation_shape(r.discrete_paths_world()[-1]))
        steps.append(r.discrete.n_steps)
    counts = {k: shapes.count(k) for k in ("pentagon", "centred square", "other")}
    return {"seeds": seeds, "counts": counts, "shapes": shapes, "steps": steps}


def scenario_numbers(name: str) -> dict:
    """What Fig. 6 shows of one scenario, in numbers."""
    r = smoothed_run(name)
    d, m, c = r.discrete, r.metrics, r.smoothed()
    final = r.discrete_paths_world()[-1]
    nn = nearest_distances(final)
    ts = time_series(name)
    out = {
        "n_robots": r.scenario.n_robots,
        "k": r.config.interaction.k,
        "order_n": r.config.mrf.order,
        "mrf_steps": d.n_steps,
        "stop_reason": d.stop_reason,
        "reached_goal": m.reached_goal,
        "final_goal_distance_m": m.final_goal_distance,
        "min_separation_discrete_m": m.min_separation,
        "final_mean_distance_m": float(m.mean_distance[-1]),
        "final_nearest_neighbour_m": [float(nn.min()), float(nn.max())],
        "smoothing": SMOOTHED[name],
        "makespan_s": c.makespan_s,
        "windows": len(c.windows),
        "min_separation_continuous_m": float(c.min_separation),
        "min_obstacle_clearance_continuous_m": None if c.min_clearance is None else float(c.min_clearance),
        "v_max": c.v_max,
        "stops_per_robot": ts.stops().tolist(),
    }
    if r.scenario.n_robots == 5 and r.scenario.goal is None:
        out["formation"] = formation_shape(final)
    return out


def _view(r: Result, world: np.ndarray, free_space: bool) -> tuple[float, float, float, float]:
    """Axis limits: the whole map, or (free space) a square around the swarm's paths."""
    if not free_space:
        return r.scenario.grid.extent
    lo, hi = world.reshape(-1, 2).min(axis=0), world.reshape(-1, 2).max(axis=0)
    c, half = (lo + hi) / 2, max(hi - lo) / 2 + 2.5
    return (c[0] - half, c[0] + half, c[1] - half, c[1] + half)


def _discrete_panel(ax, r: Result) -> None:
    world = r.discrete_paths_world()
    n = world.shape[1]
    plots.draw_map(ax, r.scenario.grid)
    plots.draw_paths(ax, r.scenario.grid, [world[:, i] for i in range(n)], r.scenario.goal_world, lw=1.3)
    colors = plots._robot_colors(n)
    for i in range(n):
        ax.plot(world[1:-1, i, 0], world[1:-1, i, 1], ".", ms=3, color=colors[i])
    x0, x1, y0, y1 = _view(r, world, r.scenario.goal is None)
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)


def _smooth_panel(ax, r: Result) -> None:
    world = r.discrete_paths_world()
    c = r.smoothed()
    t = np.linspace(0.0, c.makespan_s, int(c.makespan_s * 40) + 2)
    pos = c.positions(t)
    n = pos.shape[1]
    plots.draw_map(ax, r.scenario.grid)
    for i in range(n):
        ax.plot(world[:, i, 0], world[:, i, 1], ":", color="0.55", lw=0.8)
    plots.draw_paths(ax, r.scenario.grid, [pos[:, i] for i in range(n)], r.scenario.goal_world, lw=1.5)
    x0, x1, y0, y1 = _view(r, world, r.scenario.goal is None)
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)


def make_fig6(out: Path, quick: bool = False) -> list[Path]:
    """Write ``fig6_trajectories.png`` (2 x 4 panels as in the paper)."""
    plt = plots._plt()
    with plots.paper_style():
        fig, axes = plt.subplots(2, 4, figsize=(18, 9.4), layout="constrained")
        for j, name in enumerate(SCENARIOS):
            r = smoothed_run(name)
            nums = scenario_numbers(name)
            _discrete_panel(axes[0, j], r)
            what = f"N = {r.scenario.n_robots}, k = {r.config.interaction.k}, {r.discrete.n_steps} steps"
            if "formation" in nums:
                what += f", {nums['formation']}"
            if r.metrics.reached_goal is not None:
                what += ", at goal" if r.metrics.reached_goal else ", goal NOT reached"
            plots.panel_title(axes[0, j], "abcd"[j], f"{name}: {what}")
            _smooth_panel(axes[1, j], r)
            how = "smoothed, one window" if SMOOTHED[name] == "single" else "receding horizon"
            plots.panel_title(axes[1, j], "efgh"[j], f"{name} {how}: {r.smoothed().makespan_s:.1f} s flight")
            axes[0, j].legend(loc="upper left", fontsize=7.5, framealpha=0.9)
        fig.suptitle("Fig. 6: final discrete trajectories (a-d; n = 2, ICM), min-snap smoothed (e, f) and smoothed "
                     "with receding-horizon planning (g, h; ours: safe regions, H = 8 steps, 50 % executed, "
                     "continuous seams;\nthe paper's rest-to-rest seams are compared in fig6_seams.png)   "
                     "green: start, blue: end, grey: obstacles, dotted: discrete paths")
        return [plots.save_figure(fig, Path(out) / "fig6_trajectories.png", dpi=90)]


def variant_numbers(name: str = "corridor") -> dict:
    """Per continuous-stage variant of ``name``: makespan, stops, snap, separation, clearance, planning time."""
    from mrfswarm.trajectory import integral_squared_derivative

    out = {}
    for v in VARIANTS:
        r = scenario_run(name, v)
        c = r.smoothed()
        ts = time_series(name, 100.0, v)
        q = r.flight_quality()
        out[v] = {
            "makespan_s": round(c.makespan_s, 2),
            # result.json's: over the longest shortest free path at v_max, as `mrfswarm run` prints it (the
            # longest flown path had been taken here, a second bound under the same name)
            "makespan_over_bound": None if q is None or q["makespan_over_bound"] is None
            else round(q["makespan_over_bound"], 2),
            "stops_per_robot": ts.stops().tolist(),
            "snap_integral": round(float(sum(integral_squared_derivative(tr, 4) for tr in c.trajectories)), 1),
            "min_separation_m": round(c.min_separation, 3),
            "min_obstacle_clearance_m": None if c.min_clearance is None else round(c.min_clearance, 3),
            "v_a_j_max": [round(c.v_max, 2), round(c.a_max, 2), round(c.j_max, 2)],
            "planning_s": round(c.timings["smoothing"] + c.timings["checking"] + c.timings["regions"], 2),
            "certified": c.certificate.ok,
        }
    return out


def variant_title(variant: str, config: Config) -> str:
    """How ``fig6_seams`` names a variant of :data:`VARIANTS`, the refinement as ``config`` runs it."""
    if variant == "paper":
        return "paper: rest at every seam (H = 4, 50 %)"
    if variant == "default":
        return "ours: safe regions, continuous seams"
    sm = config.smoothing
    how = "multiplier scaling" if sm.refinement == "scaling" else f"NLP, {sm.nlp}"
    return f"ours + step durations refined ({how})"


def make_fig6_seams(out: Path, quick: bool = False) -> list[Path]:
    """Write ``fig6_seams.png``: the corridor smoothed by the paper's receding horizon, ours, and ours refined."""
    nums = variant_numbers("corridor")
    titles = {v: variant_title(v, scenario_run("corridor", v).config) for v in VARIANTS}
    plt = plots._plt()
    with plots.paper_style():
        fig = plt.figure(figsize=(17, 9.5), layout="constrained")
        gs = fig.add_gridspec(2, 3, height_ratios=[1.35, 1])
        speed_ax = fig.add_subplot(gs[1, :])
        for j, v in enumerate(VARIANTS):
            r = scenario_run("corridor", v)
            ax = fig.add_subplot(gs[0, j])
            _smooth_panel(ax, r)
            ax.set_xlim(0, 40)
            ax.set_ylim(8, 32)
            n = nums[v]
            plots.panel_title(ax, "abc"[j], f"{titles[v]}\n{n['makespan_s']:.1f} s, stops per robot "
                              f"{np.mean(n['stops_per_robot']):.1f}, snap {n['snap_integral']:.0f}, "
                              f"min separation {n['min_separation_m']:.2f} m")
            ts = time_series("corridor", 50.0, v)
            sp = ts.speeds()
            color = ("tab:red", "tab:blue", "tab:green")[j]
            speed_ax.plot(ts.t[1:], sp, color=color, lw=0.9, alpha=0.8)
            speed_ax.plot([], [], color=color, lw=2, label=f"{titles[v]}: {n['makespan_s']:.1f} s")
        speed_ax.axhline(scenario_run("corridor", "default").config.smoothing.v_max, color="0.3", ls=":",
                         label="v_max")
        speed_ax.set_xlabel("time [s]")
        speed_ax.set_ylabel("speed of each robot [m/s]")
        speed_ax.grid(alpha=0.3)
        v_max = scenario_run("corridor", "default").config.smoothing.v_max
        speed_ax.set_ylim(0, 1.3 * v_max)  # the legend's two rows above the speeds, which stay within v_max
        speed_ax.legend(fontsize=9, loc="upper center", ncol=2)
        plots.panel_title(speed_ax, "d", "speed over time: the paper's seams stop the swarm every 2 steps; "
                          "ours do not")
        fig.suptitle("Corridor (5 robots): the continuous stage three ways (goes beyond the paper). All three are "
                     "certified: control points in safe regions, separation >= 0.5 m, v, a, j within limits")
        return [plots.save_figure(fig, Path(out) / "fig6_seams.png", dpi=90)]


def numbers_fig6_seams(quick: bool = False) -> dict:
    """The numbers behind ``fig6_seams``, for ``measured.json``."""
    return variant_numbers("corridor")


def flight_3d(quick: bool = False) -> tuple[np.ndarray, str, Result]:
    """(S, N, 3) positions of the blocks flight for Fig. 1, and what they are.

    Full mode flies the smoothed trajectories in RotorPy (Crazyflie model, the
    counterpart of the paper's Gazebo); quick mode draws the planned trajectories at the
    flight altitude.
    """
    if quick:
        r = smoothed_run("blocks")
        c = r.smoothed()
        t = np.linspace(0.0, c.makespan_s, int(c.makespan_s * 20) + 2)
        xy = c.positions(t)
        z = np.full(xy.shape[:2] + (1,), r.config.scenario.altitude)
        return np.concatenate([xy, z], axis=2), "planned (quick mode: not flown)", r
    r = scenario_run("blocks", SMOOTHED["blocks"], ("simulation.enabled=true",))
    f = r.flown()
    pos = np.stack([fl.positions for fl in f.flights], axis=1)[::5]
    return pos, (f"flown in RotorPy ({r.config.simulation.vehicle}), max tracking error "
                 f"{f.max_tracking_error * 100:.1f} cm"), r


#: The authors' own swarm sizes (their experiment data; not in the paper's figures).
AUTHORS = ("corridor10", "blocks12")


def make_authors(out: Path, quick: bool = False) -> list[Path]:
    """Write ``extra_authors_swarms.png``: corridor10 and blocks12, discrete and receding horizon."""
    plt = plots._plt()
    with plots.paper_style():
        fig, axes = plt.subplots(2, 2, figsize=(11, 11), layout="constrained")
        for j, name in enumerate(AUTHORS):
            r = scenario_run(name, "default")
            _discrete_panel(axes[0, j], r)
            goal = "at goal" if r.metrics.reached_goal else "goal NOT reached"
            plots.panel_title(axes[0, j], "ab"[j], f"{name}: N = {r.scenario.n_robots}, k = {r.config.interaction.k}, "
                              f"{r.discrete.n_steps} steps ({r.discrete.stop_reason}), {goal}")
            axes[0, j].legend(loc="upper left", fontsize=7.5, framealpha=0.9)
            _smooth_panel(axes[1, j], r)
            sep = r.smoothed().min_separation
            plots.panel_title(axes[1, j], "cd"[j], f"{name} smoothed, receding horizon: "
                              f"{r.smoothed().makespan_s:.0f} s, min separation {sep:.2f} m")
        fig.suptitle("Extra (not a paper figure): the authors' own swarm sizes, 10 drones in the corridor and 12 among "
                     "the blocks")
        return [plots.save_figure(fig, Path(out) / "extra_authors_swarms.png", dpi=90)]


def numbers_authors(quick: bool = False) -> dict:
    """The numbers behind the authors' swarm sizes, for ``measured.json``."""
    out = {}
    for name in AUTHORS:
        r = scenario_run(name, "default")
        final = r.discrete.paths[-1]
        out[name] = {
            "n_robots": r.scenario.n_robots, "k": r.config.interaction.k, "mrf_steps": r.discrete.n_steps,
            "stop_reason": r.discrete.stop_reason, "reached_goal": r.metrics.reached_goal,
            "final_goal_distance_m": r.metrics.final_goal_distance,
            "min_separation_discrete_m": r.metrics.min_separation,
            "min_separation_continuous_m": float(r.smoothed().min_separation),
            "final_cells_distinct": len({tuple(c) for c in final.tolist()}) == len(final),
            "makespan_s": r.smoothed().makespan_s,
        }
    return out


def make_fig1(out: Path, quick: bool = False) -> list[Path]:
    """Write ``fig1_flight.png``: the five robots' blocks flight in 3-D among the blocks."""
    pos, what, r = flight_3d(quick)
    grid = r.scenario.grid
    z = r.config.scenario.altitude
    n = pos.shape[1]
    colors = plots._robot_colors(n)
    plt = plots._plt()
    with plots.paper_style():
        fig = plt.figure(figsize=(10, 6.4))
        ax = fig.add_axes([-0.05, -0.05, 1.1, 1.08], projection="3d")
        occ = grid.occupied
        xs = np.arange(grid.width + 1) - 0.5
        ys = np.arange(grid.height + 1) - 0.5
        filled = np.repeat(occ[:, :, None], 2, axis=2)
        X, Y, Z = np.meshgrid(grid.origin[0] + xs * grid.resolution, grid.origin[1] + ys * grid.resolution,
                              [0.0, 1.0 * z, 2.0 * z], indexing="ij")
        ax.voxels(X, Y, Z, filled, facecolors=(0.55, 0.55, 0.55, 0.4), edgecolors=(0.45, 0.45, 0.45, 0.04))
        for i in range(n):
            ax.plot(pos[:, i, 0], pos[:, i, 1], pos[:, i, 2], "-", color=colors[i], lw=1.8)
            ax.plot(pos[:, i, 0], pos[:, i, 1], np.zeros(len(pos)), "-", color=colors[i], lw=0.6, alpha=0.35)
        ax.scatter(pos[0, :, 0], pos[0, :, 1], pos[0, :, 2], s=40, c="tab:green", edgecolors="k", depthshade=False,
                   label="start")
        ax.scatter(pos[-1, :, 0], pos[-1, :, 1], pos[-1, :, 2], s=40, c="tab:blue", edgecolors="k", depthshade=False,
                   label="end")
        ax.legend(loc="upper left", bbox_to_anchor=(0.08, 0.86), fontsize=9, frameon=False)
        x0, x1, y0, y1 = grid.extent
        ax.set_xlim(x0, x1)
        ax.set_ylim(y0, y1)
        ax.set_zlim(0, 3 * z)
        ax.set_box_aspect((x1 - x0, y1 - y0, 9 * z))
        ax.view_init(elev=38, azim=-118)
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.set_zlabel("z [m]")
        ax.set_title(f"Fig. 1: {n} quadrotors flying through the blocks ({z:g} m altitude, "
                     f"{r.smoothed().makespan_s:.0f} s)\n{what}; thin lines: shadows on the ground\n(every flight passes beside the blocks: "
                     "a 3-D plot draws no depth order)", y=0.95)
        return [plots.save_figure(fig, Path(out) / "fig1_flight.png")]


def make_gifs(out: Path, quick: bool = False) -> list[Path]:
    """Write ``anim_<scenario>.gif``: 2 frames per second of flight, played 5x faster."""
    written = []
    for name in SCENARIOS:
        r = smoothed_run(name)
        c = r.smoothed()
        frames = np.linspace(0.0, c.makespan_s, max(2, int(c.makespan_s * 2) + 1))
        path = Path(out) / f"anim_{name}.gif"
        plots.animate(path, r.scenario.grid, frames, c.positions(frames), r.scenario.goal_world, fps=10,
                      trail_s=30.0)
        written.append(path)
    return written


def numbers_fig1(quick: bool = False) -> dict:
    """The numbers behind Fig. 1, for ``measured.json``."""
    _, what, r = flight_3d(quick)
    out = {"makespan_s": r.smoothed().makespan_s, "altitude_m": r.config.scenario.altitude, "shown": what}
    if r.flight is not None:
        f = r.flight
        out.update({"max_tracking_error_m": f.max_tracking_error, "tracking_error_bound_m": f.tracking_bound,
                    "flown_min_separation_m": f.min_separation, "flown_min_clearance_m": f.min_clearance,
                    "entered_obstacle": f.in_obstacle})
    return out


def numbers_fig6(quick: bool = False) -> dict:
    """The numbers behind Fig. 6, for ``measured.json``."""
    out = {name: scenario_numbers(name) for name in SCENARIOS}
    census = formation_census()
    out["free5_formation_census"] = {k: census[k] for k in ("seeds", "counts", "steps")}
    return out
