"""Figs. 7 and 8: robot positions, swarm size against k_a and k_r, corridor distances;
swarm-energy convergence and time per MRF step.

- Fig. 7a: each robot's x and y over time (the corridor, receding horizon).
- Fig. 7b: swarm size (average inter-robot distance at convergence) of 5 free-space
  robots (``experiments/swarm_size.toml``) against k_a and k_r with a_I, b_I fixed, over
  several start seeds; combinations that break b k_r / (a k_a) < 1 or k_a > k_r are
  skipped (and listed). Extra panel (not in the paper): size against a_I at the paper's
  k_a, k_r, since the text claims smaller a_I gives tighter swarms.
- Fig. 7c: minimum and average inter-robot distance over time in the corridor.
- Fig. 8a: swarm energy per MRF step of the four scenarios. Extra panel: MRF steps to
  converge against the search order n (the paper does not give its n).
- Fig. 8b: time per MRF step against the number of robots N and the search order n
  (swarms of ``experiments/bench/mrf_step.py``'s ``swarm(N)``, timed in this process).
"""

from __future__ import annotations

import importlib.util
import logging
import statistics
import time
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from mrfswarm import plots
from mrfswarm.errors import ConfigError
from mrfswarm.figures.runs import EXPERIMENTS, SCENARIOS, discrete_run, experiment_config

log = logging.getLogger(__name__)

#: The base config of the swarm-size study.
SWARM_SIZE = "swarm_size"

#: Sweep grids: full and quick.
K_A = {False: (6, 8, 10, 12, 14, 16, 20, 24, 28), True: (6, 10, 14, 20)}
K_R = {False: (2, 3, 4, 5, 6, 8), True: (2, 4, 6)}
A_I = {False: (0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9), True: (0.4, 0.7, 0.9)}
SEEDS = {False: 5, True: 2}
#: One colour per scenario, the same in every panel.
SCENARIO_COLORS = {"free5": "tab:blue", "free10": "tab:orange", "corridor": "tab:green", "blocks": "tab:purple"}
#: Search orders of the steps-against-n study and the timing study.
ORDERS = {False: (1, 2, 4, 8, 16), True: (1, 2, 8)}
TIMING_SIZES = {False: (5, 10, 20, 50, 100, 200, 500, 1000, 2000), True: (5, 20, 100)}
TIMING_ORDERS = {False: (1, 2, 4, 8), True: (1, 2, 4)}
TIMING_STEPS = {False: 5, True: 3}
TIMING_REPEATS = 3


def valid_morse(a: float, b: float, k_a: float, k_r: float) -> str | None:
    """None if the paper's conditions hold, else which one fails (:func:`~mrfswarm.discrete.potentials.morse_violation`)."""
    from mrfswarm.discrete.potentials import morse_violation

    broken = morse_violation(a, b, k_a, k_r)
    return None if broken is None else broken[0]


# --- running many configs: the sweep runner -----------------------------------------------------


def run_points(base: str, grid: dict[str, list], seeds: int, fixed: dict[str, float] | None = None) -> list[dict]:
    """Plan ``experiments/<base>.toml`` over ``grid`` (key -> values) and seeds 0..seeds-1.

    Runs :func:`mrfswarm.sweep.run_sweep` in this process (``workers=1``: a free-space
    point plans in milliseconds, less than a spawned worker takes to start), with
    ``fixed`` applied to every point. Returns one record per (point, seed): the grid
    values and ``fixed``, ``seed``, ``size_m`` (final average inter-robot distance),
    ``steps`` (MRF steps) and ``stop_reason``.

    Raises
    ------
    MrfswarmError
        A point failed (the study only sweeps valid parameters).
    """
    import tempfile

    from mrfswarm.errors import MrfswarmError
    from mrfswarm.sweep import run_sweep

    fixed = dict(fixed or {})
    overrides = ["simulation.enabled=false", *(f"{k}={v!r}" for k, v in fixed.items())]
    with tempfile.TemporaryDirectory(prefix="mrfswarm-figs-") as tmp:
        res = run_sweep(EXPERIMENTS / f"{base}.toml", grid, tmp, workers=1, progress=False, seeds=range(seeds),
                        overrides=overrides)
    if res.failed:
        raise MrfswarmError(f"sweep of {base}: {len(res.failed)} points failed, first: {res.failed[0]['error']}")
    return [{**{k: row[k] for k in grid}, **fixed, "seed": row["seed"],
             "size_m": row["mean_inter_robot_distance_final"], "steps": row["mrf_steps"],
             "stop_reason": row["stop_reason"]} for row in res.rows]


# --- Fig. 7b -----------------------------------------------------------------------------------


@dataclass(frozen=True)
class SwarmSizeSweep:
    """The numbers behind Fig. 7b.

    Attributes
    ----------
    records
        One per (k_a, k_r, seed): ``k_a``, ``k_r``, ``seed``, ``size_m``, ``steps``.
    skipped
        (k_a, k_r, reason) combinations outside the paper's conditions.
    a, b
        The fixed a_I, b_I.
    """

    records: list[dict]
    skipped: list[tuple[float, float, str]]
    a: float
    b: float

    def mean_size(self, k_a: float, k_r: float) -> tuple[float, float]:
        """Mean and standard deviation over seeds of the swarm size at (k_a, k_r)."""
        v = [r["size_m"] for r in self.records if r["interaction.k_a"] == k_a and r["interaction.k_r"] == k_r]
        return (float(np.mean(v)), float(np.std(v))) if v else (float("nan"), float("nan"))

    def d_min(self, k_a: float, k_r: float) -> float:
        from mrfswarm.discrete.potentials import Morse

        return Morse(a=self.a, b=self.b, k_a=k_a, k_r=k_r).d_min

    def k_as(self, k_r: float) -> list[float]:
        return sorted({r["interaction.k_a"] for r in self.records if r["interaction.k_r"] == k_r})

    @property
    def k_rs(self) -> list[float]:
        return sorted({r["interaction.k_r"] for r in self.records})


@lru_cache(maxsize=None)
def swarm_size_sweep(quick: bool = False) -> SwarmSizeSweep:
    """Swarm size over the k_a x k_r grid (valid combinations only) and seeds."""
    base = experiment_config(SWARM_SIZE).interaction
    records, skipped = [], []
    for k_r in K_R[quick]:  # one sweep per k_r over its valid k_a: invalid pairs are never planned
        valid = []
        for k_a in K_A[quick]:
            why = valid_morse(base.a, base.b, k_a, k_r)
            if why is None:
                valid.append(float(k_a))
            else:
                skipped.append((float(k_a), float(k_r), why))
        if valid:
            records += run_points(SWARM_SIZE, {"interaction.k_a": valid}, SEEDS[quick], {"interaction.k_r": float(k_r)})
    return SwarmSizeSweep(records=records, skipped=skipped, a=base.a, b=base.b)


@lru_cache(maxsize=None)
def a_sweep(quick: bool = False) -> list[dict]:
    """Swarm size against a_I (b_I, k_a, k_r at the paper's values): mean over seeds per a_I."""
    base = experiment_config(SWARM_SIZE).interaction
    vals = [a for a in A_I[quick] if valid_morse(a, base.b, base.k_a, base.k_r) is None]
    recs = run_points(SWARM_SIZE, {"interaction.a": [float(a) for a in vals]}, SEEDS[quick])
    from mrfswarm.discrete.potentials import Morse

    out = []
    for a in vals:
        v = [r["size_m"] for r in recs if r["interaction.a"] == a]
        out.append({"a": a, "size_m": float(np.mean(v)), "std_m": float(np.std(v)),
                    "d_min_m": Morse(a=a, b=base.b, k_a=base.k_a, k_r=base.k_r).d_min})
    return out


# --- Fig. 8a -----------------------------------------------------------------------------------


def convergence() -> dict[str, np.ndarray]:
    """Swarm energy per MRF step of the four scenarios (the paper's parameters, n = 2)."""
    return {name: discrete_run(name).discrete.energy for name in SCENARIOS}


def energy_rises(energy: np.ndarray) -> list[int]:
    """Steps t at which the swarm energy went up (energy[t] > energy[t - 1])."""
    return [int(t) for t in np.flatnonzero(np.diff(energy) > 1e-12) + 1]


def graph_changes(name: str) -> list[bool]:
    """For each step t >= 1 of a scenario's discrete paths: did the k-NN graph's edge set change?

    An ICM step never raises the energy of the graph it optimized, so the swarm energy
    (each configuration on its own graph) can only rise at a step where the graph changed.
    """
    from mrfswarm.discrete.interaction_graph import knn_edges

    r = discrete_run(name)
    k = r.config.interaction.k
    edges = [set(map(tuple, knn_edges(p.astype(float), k).tolist())) for p in r.discrete.paths]
    return [edges[t] != edges[t - 1] for t in range(1, len(edges))]


def clique_counts(name: str) -> list[int]:
    """Number of maximal cliques of each step's k-NN graph along a scenario's discrete paths."""
    from mrfswarm.discrete.planner import graph_weights

    r = discrete_run(name)
    return [len(graph_weights(p, r.config.interaction.k).cliques) for p in r.discrete.paths]


@lru_cache(maxsize=None)
def steps_against_order(quick: bool = False) -> dict[str, dict[int, int]]:
    """MRF steps to converge per scenario and search order n."""
    return {name: {n: discrete_run(name, (f"mrf.order={n}",)).discrete.n_steps for n in ORDERS[quick]}
            for name in SCENARIOS}


#: Goals (x, y) of the steps-against-goal-distance study on the corridor map.
CORRIDOR_GOALS = ((12, 20), (20, 20), (28, 20), (35, 20))


@lru_cache(maxsize=None)
def steps_against_goal_distance() -> list[dict]:
    """MRF steps to converge in the corridor for goals at growing distance from the start."""
    rows = []
    for g in CORRIDOR_GOALS:
        r = discrete_run("corridor", (f"scenario.goal=[{g[0]}, {g[1]}]",))
        start = r.discrete_paths_world()[0].mean(axis=0)
        rows.append({"goal": list(g), "distance_m": float(np.hypot(*(np.asarray(g) - start))),
                     "steps": r.discrete.n_steps, "stop_reason": r.discrete.stop_reason,
                     "reached_goal": r.metrics.reached_goal})
    return rows


# --- Fig. 8b -----------------------------------------------------------------------------------


def _bench_swarm():
    path = EXPERIMENTS / "bench" / "mrf_step.py"
    if not path.is_file():
        raise ConfigError(f"the timing figure needs {path}")
    spec = importlib.util.spec_from_file_location("mrfswarm_bench_mrf_step", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.swarm


@lru_cache(maxsize=None)
def step_times(quick: bool = False) -> list[dict]:
    """Seconds per MRF step (ICM) for each swarm size N and search order n.

    The median over a few consecutive steps of each step's fastest of
    :data:`TIMING_REPEATS` runs (the machine is shared). The steps move a Gaussian swarm
    toward a goal in free space (k = min(7, N - 1)); one warm-up step first. Also records
    the mean label-set size (cells per robot), the work that grows with n.
    """
    from mrfswarm.discrete.planner import DiscreteProblem, mrf_step, problem_label_sets

    swarm = _bench_swarm()
    mrf_step(swarm(5), swarm(5).start)  # warm-up (imports, caches)
    rows = []
    for N in TIMING_SIZES[quick]:
        base = swarm(N)
        for n in TIMING_ORDERS[quick]:
            problem = DiscreteProblem(**{**base.__dict__, "order": n})
            pos = problem.start
            labels = problem_label_sets(problem, pos)
            ts = []
            for _ in range(TIMING_STEPS[quick]):
                best = np.inf
                for _ in range(TIMING_REPEATS):  # the same step again: the fastest is the least disturbed
                    t0 = time.perf_counter()
                    out = mrf_step(problem, pos)
                    best = min(best, time.perf_counter() - t0)
                ts.append(best)
                pos = out.positions
            rows.append({"N": N, "n": n, "k": problem.k, "step_s": statistics.median(ts),
                         "labels_per_robot": float(np.mean(labels.count))})
    return rows


# --- drawing -----------------------------------------------------------------------------------


def make_fig7(out: Path, quick: bool = False) -> list[Path]:
    """Write ``fig7_robots_size_distances.png``."""
    from mrfswarm.figures.trajectories import corridor_series

    ts = corridor_series()
    sw = swarm_size_sweep(quick)
    asw = a_sweep(quick)
    plt = plots._plt()
    with plots.paper_style():
        fig = plt.figure(figsize=(16, 10.5), layout="constrained")
        gs = fig.add_gridspec(3, 3, height_ratios=[1, 1, 1.15], width_ratios=[1.25, 1, 0.75])
        ax_x = fig.add_subplot(gs[0, 0])
        ax_y = fig.add_subplot(gs[1, 0], sharex=ax_x)
        colors = plots._robot_colors(ts.positions.shape[1])
        for i in range(ts.positions.shape[1]):
            ax_x.plot(ts.t, ts.positions[:, i, 0], color=colors[i], lw=1.3, label=f"robot {i + 1}")
            ax_y.plot(ts.t, ts.positions[:, i, 1], color=colors[i], lw=1.3)
        ax_x.set_ylabel("x [m]")
        ax_y.set_ylabel("y [m]")
        ax_y.set_xlabel("time [s]")
        ax_x.legend(ncol=5, fontsize=8, loc="lower right")
        for ax in (ax_x, ax_y):
            ax.grid(alpha=0.3)
        plots.panel_title(ax_x, "a", "trajectories of individual robots (corridor, receding horizon)")

        ax = fig.add_subplot(gs[0:2, 1])
        cmap = plt.get_cmap("viridis")
        for j, k_r in enumerate(sw.k_rs):
            c = cmap(0.85 * j / max(1, len(sw.k_rs) - 1))
            kas = sw.k_as(k_r)
            m = np.array([sw.mean_size(k_a, k_r) for k_a in kas])
            ax.errorbar(kas, m[:, 0], yerr=m[:, 1], fmt="-o", ms=4, color=c, capsize=2, label=f"$k_r$ = {k_r:g}")
            ax.plot(kas, [sw.d_min(k_a, k_r) for k_a in kas], "--", color=c, lw=0.9, alpha=0.8)
        ax.set_xlabel("$k_a$ [cells] (= m at the paper's 1 m cells)")
        ax.set_ylabel("swarm size: average inter-robot distance [m]")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8.5, title=f"$a_I$ = {sw.a:g}, $b_I$ = {sw.b:g}", title_fontsize=8.5)
        n_seeds = len({r['seed'] for r in sw.records})
        plots.panel_title(ax, "b", f"swarm size against $k_a$, $k_r$ (5 robots, {n_seeds} seeds)")
        ax.text(0.98, 0.02, f"dashed: pair minimum $d_{{min}}$\n"
                f"{len(sw.skipped)} invalid ($k_a$, $k_r$) skipped:\n"
                "$k_a \\leq k_r$ or $b_I k_r / (a_I k_a) \\geq 1$", transform=ax.transAxes, ha="right",
                va="bottom", fontsize=8.5, bbox={"fc": "w", "ec": "0.7", "alpha": 0.9})

        ax = fig.add_subplot(gs[0:2, 2])
        a = [r["a"] for r in asw]
        ax.errorbar(a, [r["size_m"] for r in asw], yerr=[r["std_m"] for r in asw], fmt="-o", ms=4,
                    color="tab:red", capsize=2, label="measured")
        ax.plot(a, [r["d_min_m"] for r in asw], "--", color="tab:red", lw=0.9, label="$d_{min}$")
        ax.set_xlabel("$a_I$")
        ax.set_ylabel("swarm size [m]")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8.5)
        base = experiment_config(SWARM_SIZE).interaction
        ax.set_title(f"(b, extra) size against $a_I$\n($k_a$ = {base.k_a:g}, $k_r$ = {base.k_r:g}, "
                     f"$b_I$ = {base.b:g})")

        ax = fig.add_subplot(gs[2, :])
        ax.plot(ts.t, ts.mean_distance, lw=1.6, label="average distance")
        ax.plot(ts.t, ts.min_distance, lw=1.6, label="minimum distance")
        ax.axhline(ts.safety, color="r", ls="--", lw=1, label=f"safety distance {ts.safety:g} m")
        ex = ts.expansion()
        ax.axvspan(2.0, 4.0, color="0.85", alpha=0.6, label="paper: expansion peak 2-4 s")
        if ex["rise_from_s"] is not None:
            ax.annotate(f"initial expansion: {ex['start_m']:.1f} -> {ex['peak_m']:.1f} m\n"
                        f"({ex['rise_from_s']:.1f}-{ex['peak_reached_s']:.1f} s)",
                        xy=(ex["peak_reached_s"], ex["peak_m"]), xytext=(ex["peak_reached_s"] + 4, ex["peak_m"] - 0.1),
                        arrowprops={"arrowstyle": "->", "color": "0.3"}, fontsize=9, va="top")
        ax.set_xlabel("time [s]")
        ax.set_ylabel("distance [m]")
        ax.set_ylim(bottom=0)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8.5, loc="upper right", ncol=2)
        plots.panel_title(ax, "c", "minimum and average distance between the robots, narrow corridor (5 robots)")
        fig.suptitle("Fig. 7: individual robot trajectories, swarm size against the Morse ranges, corridor distances")
        return [plots.save_figure(fig, Path(out) / "fig7_robots_size_distances.png", dpi=90)]


def make_fig8(out: Path, quick: bool = False) -> list[Path]:
    """Write ``fig8_convergence_timing.png``."""
    energies = convergence()
    so = steps_against_order(quick)
    times = step_times(quick)
    plt = plots._plt()
    with plots.paper_style():
        fig, axes = plt.subplots(1, 3, figsize=(17, 5.2), layout="constrained",
                                 gridspec_kw={"width_ratios": [1.2, 0.85, 1]})
        ax = axes[0]
        for name, e in energies.items():
            c = SCENARIO_COLORS[name]
            ax.plot(np.arange(len(e)), e, "-o", ms=3, lw=1.3, color=c, label=f"{name}: {len(e) - 1} steps")
            up = energy_rises(e)
            if up:
                ax.plot(up, e[up], "^", ms=8, mfc="none", mec="k", mew=1.1)
        ax.plot([], [], "^", ms=8, mfc="none", mec="k", label="energy rose: the k-NN graph changed")
        ax.set_yscale("log")
        ax.set_xlabel("MRF step")
        ax.set_ylabel("swarm energy (log scale)")
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=8.5)
        plots.panel_title(ax, "a", "swarm-energy convergence (n = 2, ICM)")

        ax = axes[1]
        for name, d in so.items():
            ax.plot(list(d), list(d.values()), "-o", ms=4, color=SCENARIO_COLORS[name], label=name)
        ax.axhline(3, color="0.4", ls=":", lw=1.2, label="paper: free space under 3")
        ax.set_xscale("log", base=2)
        ax.set_xticks(list(ORDERS[quick]), [str(n) for n in ORDERS[quick]])
        ax.set_xlabel("search order n")
        ax.set_ylabel("MRF steps to converge")
        ax.set_ylim(bottom=0)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8.5)
        plots.panel_title(ax, "extra", "steps to converge against the search order n")

        ax = axes[2]
        orders = sorted({r["n"] for r in times})
        cmap = plt.get_cmap("plasma")
        for j, n in enumerate(orders):
            rows = [r for r in times if r["n"] == n]
            ax.plot([r["N"] for r in rows], [r["step_s"] * 1e3 for r in rows], "-o", ms=4,
                    color=cmap(j / max(1, len(orders))), label=f"n = {n}")
        ax.set_xscale("log")
        ax.set_yscale("log")
        plots.plain_log_ticks(ax.yaxis)
        ax.set_xlabel("number of robots N")
        ax.set_ylabel("time per MRF step [ms]")
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=8.5, title="search order", title_fontsize=8.5)
        plots.panel_title(ax, "b", "time per MRF step (ICM, Python/numpy, this machine)")
        fig.suptitle("Fig. 8: convergence of the swarm energy and time per MRF step")
        return [plots.save_figure(fig, Path(out) / "fig8_convergence_timing.png")]


def numbers_fig7(quick: bool = False) -> dict:
    """The numbers behind Fig. 7, for ``measured.json``."""
    from mrfswarm.figures.trajectories import corridor_series

    ts = corridor_series()
    sw = swarm_size_sweep(quick)
    table = {f"k_r={k_r:g}": {f"k_a={k_a:g}": round(sw.mean_size(k_a, k_r)[0], 2) for k_a in sw.k_as(k_r)}
             for k_r in sw.k_rs}
    steps = [r["steps"] for r in sw.records]
    by_dmin: dict[int, list[int]] = {}
    for r in sw.records:
        by_dmin.setdefault(round(sw.d_min(r["interaction.k_a"], r["interaction.k_r"])), []).append(r["steps"])
    pts = sorted({(r["interaction.k_a"], r["interaction.k_r"]) for r in sw.records})
    size = np.array([sw.mean_size(*p)[0] for p in pts])
    dmin = np.array([sw.d_min(*p) for p in pts])
    return {
        "corridor_expansion": ts.expansion(),
        "corridor_min_distance_m": float(ts.min_distance.min()),
        "corridor_safety_distance_m": ts.safety,
        "corridor_makespan_s": float(ts.t[-1]),
        "swarm_size_m": table,
        "d_min_m": {f"k_r={k_r:g}": {f"k_a={k_a:g}": round(sw.d_min(k_a, k_r), 2) for k_a in sw.k_as(k_r)}
                    for k_r in sw.k_rs},
        "skipped": [[ka, kr, why] for ka, kr, why in sw.skipped],
        "sweep_steps_range": [min(steps), max(steps)],
        "sweep_all_converged": all(r["stop_reason"] == "converged" for r in sw.records),
        "sweep_runs": len(sw.records),
        "size_over_d_min_range": [float((size / dmin).min()), float((size / dmin).max())],
        "size_d_min_correlation": float(np.corrcoef(size, dmin)[0, 1]),
        "mean_steps_by_d_min_m": {str(k): round(float(np.mean(v)), 1) for k, v in sorted(by_dmin.items())},
        "seeds": len({r["seed"] for r in sw.records}),
        "size_against_a": a_sweep(quick),
    }


def numbers_fig8(quick: bool = False) -> dict:
    """The numbers behind Fig. 8, for ``measured.json``."""
    energies = convergence()
    return {
        "steps": {k: len(e) - 1 for k, e in energies.items()},
        "energy_first_last": {k: [float(e[0]), float(e[-1])] for k, e in energies.items()},
        "energy_rises_at_steps": {k: energy_rises(e) for k, e in energies.items()},
        "rises_where_graph_changed": {k: all(graph_changes(k)[t - 1] for t in energy_rises(e))
                                      for k, e in energies.items()},
        "cliques_per_step": {k: clique_counts(k) for k in SCENARIOS if k.startswith("free")},
        "steps_against_order": {k: {str(n): v for n, v in d.items()} for k, d in steps_against_order(quick).items()},
        "corridor_steps_against_goal_distance": steps_against_goal_distance(),
        "step_time_ms": [{"N": r["N"], "n": r["n"], "k": r["k"], "ms": round(r["step_s"] * 1e3, 3),
                          "labels_per_robot": round(r["labels_per_robot"], 2)} for r in step_times(quick)],
    }
