"""Ablation of the MRF optimizer: every installed method on the paper's scenarios.

For each scenario (discrete stage only, ``smoothing.enabled = false``) and each method of
``solvers.mrf.METHODS`` (default: every installed one except the exhaustive ``exact``),
plans the discrete paths with ``mrfswarm.discrete.planner.plan_discrete`` (the config's
``max_steps``, ``tol``, ``patience``; ``Options(seed=SEED)``, so Gibbs is reproducible)
and records:

- the swarm energy trace (energy of x^t on its own interaction graph, per step) and the
  final swarm energy, also relative to ICM's in the same scenario;
- per MRF step, on the very step MRF the method solved (the planner's ``StepOutcome.model``, with
  the step's trimmed label sets and congested field; its energy of the method's labelling is
  checked against the method's own): TRW-S's lower bound LB (TRW-S run to ``BOUND_ITER``
  iterations), ICM's energy on the same MRF and, where the step MRF has at most
  ``EXACT_LIMIT`` labellings, its exact optimum (``exact``). Reported: the relative gap
  to the bound (E - LB) / |LB| and to the optimum (E - E*) / |E*| (mean and max over
  steps), the share of the step's possible decrease that the method missed,
  (E - LB) / (E_stay - LB), the steps proved optimal (E = E*, or E = LB where there is no
  E*), and how many steps the method ended below / above ICM on the same MRF;
- MRF steps and the stop reason, optimizer and whole-step time per step (mean), the
  minimum separation (during moves included), the total path length, and whether the
  swarm's centroid reached the goal.

Writes ``OUT/ablation.csv`` (one row per scenario and method), ``OUT/ablation.steps.csv``
(one row per MRF step), ``OUT/ablation.md`` (a Markdown table) and ``OUT/ablation.png``
(swarm energy per step, one panel per scenario, and summary bars).

    PYTHONPATH=. python experiments/ablation.py                  # ~1 minute
    PYTHONPATH=. python experiments/ablation.py --quick          # 10 steps per run
    PYTHONPATH=. python experiments/ablation.py --scenarios corridor --methods icm,trws --out /tmp/abl
"""

from __future__ import annotations

import argparse
import csv
import math
import sys
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from mrfswarm.config import load_config
from mrfswarm.discrete.planner import AUTO_RULES, StepOutcome, plan_discrete
from mrfswarm.metrics import discrete_metrics
from mrfswarm.pipeline import mrf_options
from mrfswarm.scenario import build_scenario
from solvers import mrf
from solvers.errors import SolverNotFound

ROOT = Path(__file__).resolve().parents[1]
EXPERIMENTS = ROOT / "experiments"
SCENARIOS = ("free5", "free10", "corridor", "blocks")
#: Iterations of the TRW-S run that gives each step's lower bound.
BOUND_ITER = 300
QUICK_STEPS = 10
#: Step MRFs with at most this many labellings also get their exact optimum.
EXACT_LIMIT = 200_000
#: Relative gap below which a step counts as solved to optimality.
CERTIFIED = 1e-9

COLUMNS = [
    "scenario", "n_robots", "k", "order", "method", "steps", "stop_reason", "initial_energy", "final_energy",
    "final_vs_icm_pct", "gap_mean_pct", "gap_max_pct", "opt_gap_mean_pct", "opt_gap_max_pct", "exact_solves",
    "missed_mean_pct", "missed_max_pct", "steps_optimal", "mrf_solves", "steps_below_icm", "steps_above_icm", "optimizer_ms_per_step", "step_ms", "repaired",
    "min_separation_m", "path_length_m", "final_goal_distance_m", "reached_goal",
]
STEP_COLUMNS = ["scenario", "method", "step", "moved", "swarm_energy", "step_energy_stay", "step_energy",
                "lower_bound", "optimum", "icm_step_energy", "iterations", "optimizer_ms"]


@dataclass
class StepRecord:
    """One MRF step as the method solved it, with the reference numbers on the same MRF."""

    moved: int
    energy_stay: float
    energy: float
    lower_bound: float
    optimum: float
    icm_energy: float
    iterations: int
    optimizer_s: float

    @property
    def gap(self) -> float:
        """(E - LB) / |LB|."""
        return (self.energy - self.lower_bound) / max(abs(self.lower_bound), 1e-300)

    @property
    def opt_gap(self) -> float:
        """(E - E*) / |E*| (nan without the exact optimum)."""
        return (self.energy - self.optimum) / max(abs(self.optimum), 1e-300)

    @property
    def optimal(self) -> bool:
        """Proved optimal: equal to the exact optimum, or (without one) to the lower bound."""
        return bool((self.opt_gap if np.isfinite(self.optimum) else self.gap) <= CERTIFIED)

    @property
    def missed(self) -> float:
        """Share of the possible decrease E_stay - LB that the step did not achieve."""
        room = self.energy_stay - self.lower_bound
        return (self.energy - self.lower_bound) / room if room > 1e-12 * max(1.0, abs(self.lower_bound)) else 0.0


@dataclass
class Run:
    """One method on one scenario."""

    scenario: str
    method: str
    row: dict
    energy: np.ndarray
    records: list[StepRecord] = field(default_factory=list)


def scenario_path(name: str) -> Path:
    """A scenario name (``corridor``) or a path to a TOML config."""
    p = Path(name)
    if p.suffix == ".toml":
        return p
    return EXPERIMENTS / f"{name}.toml"


def default_methods() -> list[str]:
    """Every installed method except the exhaustive ones."""
    return mrf.METHODS.available(lambda c: not c.optimal)


def _recorder(records: list[StepRecord]):
    """An ``on_step`` callback: measure the references on the step's MRF."""
    bound_options = mrf.Options(max_iter=BOUND_ITER, tol=1e-12)

    def on_step(t: int, out: StepOutcome) -> None:
        # the planner's own step MRF: one rebuilt from the positions missed the step's trimmed label sets (a
        # robot's moves given back by mrf.trim_escape) and congested goal field, and a config with the default
        # rules ended in "AssertionError: step 12: the rebuilt step MRF gives 156.96, the planner's 157.54"
        model = out.model
        e = model.energy(out.result.labels)
        if not math.isclose(e, out.energy_after, rel_tol=1e-9, abs_tol=1e-9):
            raise AssertionError(f"step {t}: the step MRF gives {e}, the planner's {out.energy_after}")
        lb = mrf.minimize(model, "trws", bound_options).lower_bound
        small = np.prod(model.n_labels.astype(float)) <= EXACT_LIMIT
        records.append(StepRecord(
            moved=out.moved,
            energy_stay=out.energy_before,
            energy=out.energy_after,
            lower_bound=float(lb) if lb is not None else float("nan"),
            optimum=mrf.minimize(model, "exact").energy if small else float("nan"),
            icm_energy=mrf.minimize(model, "icm").energy,
            iterations=out.result.iterations,
            optimizer_s=out.timings["optimizer"],
        ))

    return on_step


def run_one(config: Path, method: str, max_steps: int | None = None, seed: int = 0) -> Run:
    """Plan one scenario's discrete stage with ``method`` and measure it."""
    cfg = load_config(config, ["smoothing.enabled=false", f"mrf.method={method}"])
    scn = build_scenario(cfg)
    problem = scn.discrete_problem()
    if problem.contested == "auto":  # one plan per method, its steps measured: the first rule "auto" tries
        problem = replace(problem, contested=AUTO_RULES[0])
    records: list[StepRecord] = []
    plan = plan_discrete(problem, method=method, max_steps=max_steps or cfg.mrf.max_steps, tol=cfg.mrf.tol,
                         patience=cfg.mrf.patience, options=mrf_options(cfg, seed),
                         on_step=_recorder(records), progress=cfg.mrf.progress,
                         arrival=cfg.mrf.arrival)
    if plan.stop_reason == "stalled":
        del records[plan.n_steps:]  # the planner drops the steps after the energy's minimum; so do we
    m = discrete_metrics(plan.paths, scn.grid.occupied, scn.grid.resolution, scn.goal, scn.goal_radius)
    gaps = np.array([r.gap for r in records])
    missed = np.array([r.missed for r in records])
    opt = np.array([r.opt_gap for r in records if np.isfinite(r.optimum)])
    steps_ms = sum(plan.timings.values()) * 1e3
    tol = 1e-9
    row = {
        "scenario": config.stem,
        "n_robots": scn.n_robots,
        "k": problem.k,
        "order": problem.order,
        "method": method,
        "steps": plan.n_steps,
        "stop_reason": plan.stop_reason,
        "initial_energy": float(plan.energy[0]),
        "final_energy": float(plan.energy[-1]),
        "final_vs_icm_pct": float("nan"),
        "gap_mean_pct": 100 * float(gaps.mean()),
        "gap_max_pct": 100 * float(gaps.max()),
        "opt_gap_mean_pct": 100 * float(opt.mean()) if opt.size else float("nan"),
        "opt_gap_max_pct": 100 * float(opt.max()) if opt.size else float("nan"),
        "exact_solves": int(opt.size),
        "missed_mean_pct": 100 * float(missed.mean()),
        "missed_max_pct": 100 * float(missed.max()),
        "steps_optimal": sum(r.optimal for r in records),
        "mrf_solves": len(records),
        "steps_below_icm": sum(r.energy < r.icm_energy - tol * max(1.0, abs(r.icm_energy)) for r in records),
        "steps_above_icm": sum(r.energy > r.icm_energy + tol * max(1.0, abs(r.icm_energy)) for r in records),
        "optimizer_ms_per_step": float(np.mean([r.optimizer_s for r in records])) * 1e3,
        "step_ms": float(np.mean(steps_ms)) if len(steps_ms) else float("nan"),
        "repaired": int(sum(s["repaired"] for s in plan.steps)),
        "min_separation_m": float(m.min_separation),
        "path_length_m": float(m.path_lengths.sum()),
        "final_goal_distance_m": m.final_goal_distance,
        "reached_goal": m.reached_goal,
    }
    return Run(config.stem, method, row, plan.energy, records)


def run(scenarios: list[str], methods: list[str], max_steps: int | None = None, seed: int = 0,
        log=None) -> list[Run]:
    """Every method on every scenario; fills ``final_vs_icm_pct`` where ICM was run."""
    runs = []
    for name in scenarios:
        path = scenario_path(name)
        here = []
        for method in methods:
            t0 = time.perf_counter()
            r = run_one(path, method, max_steps, seed)
            here.append(r)
            if log:
                log(f"{r.scenario:>10} {method:>13}: {r.row['steps']:>3} steps, {r.row['stop_reason']}, "
                    f"final energy {r.row['final_energy']:.6g}, gap max {r.row['gap_max_pct']:.3g} % "
                    f"({time.perf_counter() - t0:.1f} s)")
        icm = next((r for r in here if r.method == "icm"), None)
        if icm is not None:
            ref = icm.row["final_energy"]
            for r in here:
                r.row["final_vs_icm_pct"] = 100 * (r.row["final_energy"] - ref) / abs(ref)
        runs += here
    return runs


def _fmt(v) -> str:
    if v is None:
        return ""
    if isinstance(v, float):
        return "nan" if math.isnan(v) else f"{v:.10g}"
    return str(v)


def write_csv(runs: list[Run], out: Path) -> None:
    with open(out / "ablation.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=COLUMNS)
        w.writeheader()
        for r in runs:
            w.writerow({k: _fmt(r.row[k]) for k in COLUMNS})
    with open(out / "ablation.steps.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(STEP_COLUMNS)
        for r in runs:
            for t, s in enumerate(r.records, start=1):
                swarm = r.energy[t] if t < len(r.energy) else r.energy[-1]
                w.writerow([r.scenario, r.method, t, s.moved, _fmt(float(swarm)), _fmt(s.energy_stay),
                            _fmt(s.energy), _fmt(s.lower_bound), _fmt(s.optimum), _fmt(s.icm_energy), s.iterations,
                            _fmt(s.optimizer_s * 1e3)])


def _pct(v: float | None, digits: int = 2) -> str:
    """A percentage for the table: rounding noise (|v| < 1e-7 %) shows as 0."""
    if v is None or math.isnan(v):
        return "–"
    if abs(v) < 1e-7:
        return "0"
    if abs(v) < 10 ** -digits:
        return f"{v:.0e}"
    return f"{v:.{digits}f}"


def markdown(runs: list[Run], command: str) -> str:
    head = ["scenario", "method", "steps", "stop", "final energy", "vs ICM %", "LB gap mean / max %",
            "opt gap mean / max %", "optimal steps", "below / above ICM", "opt ms/step", "step ms",
            "min sep m", "path m", "goal"]
    lines = [
        "# MRF optimizer ablation (discrete stage)",
        "",
        f"Generated by `{command}`. One row per scenario and method; every method minimizes the same",
        "step MRF (pairwise reduction of the clique energy, label sets with the paper's heuristics),",
        "from the same start, with the same seeds. Per-step numbers: `ablation.steps.csv`.",
        "",
        "- *final energy*: swarm energy of the final configuration on its own interaction graph;",
        "  *vs ICM %*: relative to ICM's final energy on the same scenario (negative = lower).",
        "- *LB gap*: per MRF step, (E − LB) / |LB|, E the method's step energy, LB the TRW-S lower",
        f"  bound on that same step MRF ({BOUND_ITER} iterations); mean / max over the run's MRF solves.",
        "- *opt gap*: the same against the exact optimum E* of the step MRF, computed where it has at",
        f"  most {EXACT_LIMIT:,} labellings (in parentheses: how many MRF solves that was; – if none).",
        "- *optimal steps*: MRF solves proved optimal (E = E*, or E = LB where E* is not computed) /",
        "  all MRF solves of the plan (including the last one, which moves nobody when the run converges;",
        "  a *stalled* run ends at its swarm energy's minimum, and the solves after it are dropped).",
        "- *below / above ICM*: MRF solves where the method's step energy is lower / higher than ICM's",
        "  on the same step MRF (same positions).",
        "- *opt ms/step*: optimizer time per MRF step; *step ms*: the whole step (graph, cliques, label",
        "  sets, energy tables, optimizer); *min sep*: smallest distance between two robots over the",
        "  run, during moves included; *path*: total path length of all robots; *goal*: swarm centroid",
        "  within the goal radius at the end (– without a goal).",
        "",
        "| " + " | ".join(head) + " |",
        "|" + "|".join(["---"] * 4 + ["---:"] * (len(head) - 4)) + "|",
    ]
    for r in runs:
        w = r.row
        goal = "–" if w["reached_goal"] is None else ("yes" if w["reached_goal"] else "no")
        cells = [w["scenario"], w["method"], str(w["steps"]), w["stop_reason"], f"{w['final_energy']:.5g}",
                 _pct(w["final_vs_icm_pct"]),
                 f"{_pct(w['gap_mean_pct'], 3)} / {_pct(w['gap_max_pct'], 3)}",
                 (f"{_pct(w['opt_gap_mean_pct'], 3)} / {_pct(w['opt_gap_max_pct'], 3)} ({w['exact_solves']})"
                  if w["exact_solves"] else "–"),
                 f"{w['steps_optimal']}/{w['mrf_solves']}", f"{w['steps_below_icm']} / {w['steps_above_icm']}",
                 f"{w['optimizer_ms_per_step']:.2f}", f"{w['step_ms']:.2f}", f"{w['min_separation_m']:.2f}",
                 f"{w['path_length_m']:.1f}", goal]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def plot(runs: list[Run], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib import ticker

    scenarios = list(dict.fromkeys(r.scenario for r in runs))
    methods = list(dict.fromkeys(r.method for r in runs))
    colours = {m: plt.cm.tab10(i % 10) for i, m in enumerate(methods)}
    styles = ["-", "--", "-.", ":", (0, (5, 1)), (0, (3, 1, 1, 1))]
    n_panels = len(scenarios) + 2
    cols = min(3, n_panels)
    rows = math.ceil(n_panels / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(5.2 * cols, 3.9 * rows), squeeze=False)
    axes = axes.ravel()
    for ax, sc in zip(axes, scenarios):
        for i, r in enumerate(x for x in runs if x.scenario == sc):
            ax.plot(np.arange(len(r.energy)), r.energy, linestyle=styles[i % len(styles)], lw=1.8,
                    color=colours[r.method], label=f"{r.method} ({r.row['steps']} steps)")
        e = np.concatenate([r.energy for r in runs if r.scenario == sc])
        if e.min() > 0 and e.max() / e.min() > 5:
            ax.set_yscale("log")
            ax.yaxis.set_major_locator(ticker.LogLocator(subs=(1.0, 2.0, 3.0, 5.0, 7.0)))
            ax.yaxis.set_major_formatter(ticker.FuncFormatter(lambda v, _: f"{v:g}"))
            ax.yaxis.set_minor_formatter(ticker.NullFormatter())
        first = next(r for r in runs if r.scenario == sc)
        ax.set_title(f"{sc}: N = {first.row['n_robots']}, k = {first.row['k']}, n = {first.row['order']}")
        ax.set_xlabel("MRF step")
        ax.set_ylabel("swarm energy")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    # summary bars: final energy vs ICM, and optimizer time per step
    x = np.arange(len(scenarios))
    width = 0.8 / max(1, len(methods))
    ax_e, ax_t = axes[len(scenarios)], axes[len(scenarios) + 1]
    for j, m in enumerate(methods):
        rel = [next((r.row["final_vs_icm_pct"] for r in runs if r.scenario == sc and r.method == m), np.nan)
               for sc in scenarios]
        ms = [next((r.row["optimizer_ms_per_step"] for r in runs if r.scenario == sc and r.method == m), np.nan)
              for sc in scenarios]
        ax_e.bar(x + (j - (len(methods) - 1) / 2) * width, rel, width, color=colours[m], label=m)
        ax_t.bar(x + (j - (len(methods) - 1) / 2) * width, ms, width, color=colours[m], label=m)
    ax_e.axhline(0, color="k", lw=0.8)
    for i, sc in enumerate(scenarios):
        rel = [r.row["final_vs_icm_pct"] for r in runs if r.scenario == sc]
        if all(abs(v) < 1e-9 for v in rel if not math.isnan(v)):
            ax_e.annotate("all = ICM", (i, 0), ha="center", va="top", fontsize=8,
                          xytext=(0, -4), textcoords="offset points")
    ax_e.set_title("final swarm energy relative to ICM")
    ax_e.set_ylabel("%  (negative = lower than ICM)")
    ax_t.set_title("optimizer time per MRF step")
    ax_t.set_ylabel("ms")
    ax_t.set_yscale("log")
    for ax in (ax_e, ax_t):
        ax.set_xticks(x, scenarios)
        ax.grid(alpha=0.3, axis="y")
    ax_e.legend(fontsize=8)  # the time panel uses the same colours
    for ax in axes[n_panels:]:
        ax.axis("off")
    fig.suptitle("MRF optimizer ablation: discrete stage, same scenarios and seeds for every method")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> list[Run]:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenarios", default=",".join(SCENARIOS),
                    help="comma-separated names in experiments/ or paths to TOML configs")
    ap.add_argument("--methods", default=None, help="comma-separated MRF methods (default: installed, no exact)")
    ap.add_argument("--out", type=Path, default=ROOT / "paper_figs")
    ap.add_argument("--quick", action="store_true", help=f"at most {QUICK_STEPS} MRF steps per run")
    ap.add_argument("--max-steps", type=int, default=None, help="override every config's mrf.max_steps")
    ap.add_argument("--seed", type=int, default=0, help="optimizer seed (Gibbs)")
    args = ap.parse_args(argv)
    methods = args.methods.split(",") if args.methods else default_methods()
    for m in methods:
        try:
            mrf.METHODS.get(m)  # unknown names fail before any work
        except SolverNotFound as e:
            ap.error(str(e))
    for name in args.scenarios.split(","):
        if not scenario_path(name).is_file():
            ap.error(f"no scenario config {scenario_path(name)}")
    max_steps = args.max_steps or (QUICK_STEPS if args.quick else None)
    t0 = time.perf_counter()
    runs = run(args.scenarios.split(","), methods, max_steps, args.seed, log=print)
    args.out.mkdir(parents=True, exist_ok=True)
    write_csv(runs, args.out)
    command = "python experiments/ablation.py " + " ".join(argv if argv is not None else sys.argv[1:])
    (args.out / "ablation.md").write_text(markdown(runs, command.strip()))
    plot(runs, args.out / "ablation.png")
    print(f"wrote {args.out / 'ablation.csv'}, ablation.steps.csv, ablation.md, ablation.png "
          f"({time.perf_counter() - t0:.0f} s)")
    return runs


if __name__ == "__main__":
    main()
