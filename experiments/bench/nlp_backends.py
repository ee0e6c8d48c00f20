"""Benchmark every registered NLP backend on the time refinement's problems of real windows.

The scenario's discrete plan is smoothed by the receding horizon with the time refinement
on by Ipopt (``--nlp ipopt``); at each of the first ``--windows`` windows, before the run's
own refinement (so the run goes on as ``mrfswarm run --nlp ipopt`` would), the window's
time-allocation NLP (:meth:`RecedingHorizon.time_allocation`: f(T) = J*(T) + w N sum(T)
over the step durations, every evaluation the window's QP at the NLP refinement's
iteration budget, the gradient from its multipliers) is built afresh for every backend of
``solvers.nlp.BACKENDS``, with the row sum(T) <= the QP's sum where the backend takes
linear rows (:meth:`RecedingHorizon._not_longer`, as the refinement poses it), and
minimized from the QP's durations, with two settings:

- ``run``: the settings the refinement uses (``NLP_OPTIONS``: tol 1e-4, 12 iterations);
- ``converged``: tol 1e-4 and 100 iterations, to compare where each backend ends.

Per window, setting and backend: status, iterations, calls of f and of its gradient (as
dispatch counts them), distinct points evaluated (``points``: each one a window QP, the
refinement's cache answers repeated calls) and those where f was not defined (``NaN``: the
QP had no solution), wall time, the objective at the returned point, the best objective
among the points evaluated that last no longer than the QP's (``best seen``: what the
refinement keeps, if it certifies; L-BFGS-B, without the row, also evaluates longer ones),
and against Ipopt in the same run and window: both relative gaps (negative: lower than
Ipopt's) and the time ratio. Prints a table and writes every row to
``experiments/bench/results/nlp_backends.csv`` (``--out`` to change). The machine's load
is printed: timings on a shared machine vary by tens of percent.

    PYTHONPATH=. python experiments/bench/nlp_backends.py                    # corridor, 4 windows, ~7 minutes (2 loaded cores)
    PYTHONPATH=. python experiments/bench/nlp_backends.py --config experiments/free5.toml --windows 2
"""

from __future__ import annotations

import argparse
import os
import pathlib
import time

import numpy as np
from csv_table import write_csv

from mrfswarm.config import load_config
from mrfswarm.continuous.receding_horizon import NLP_OPTIONS, SAME_LENGTH, RecedingHorizon
from mrfswarm.pipeline import plan, qp_options
from solvers import nlp

ROOT = pathlib.Path(__file__).resolve().parents[2]
RESULTS = pathlib.Path(__file__).parent / "results" / "nlp_backends.csv"
BASELINE = "ipopt"
SETTINGS = {"run": NLP_OPTIONS, "converged": nlp.Options(tol=NLP_OPTIONS.tol, max_iter=100)}
COLUMNS = ["window", "steps", "setting", "backend", "status", "iterations", "evaluations", "gradient_evaluations",
           "points", "nan_points", "time_s", "f_start", "objective", "gap_vs_ipopt", "best_seen", "best_gap_vs_ipopt", "time_vs_ipopt"]


class Benchmarked(RecedingHorizon):
    """The receding horizon, each of whose first windows' NLP is also minimized by every backend."""

    def __init__(self, *args, windows: int, backends: list[str], **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.bench_windows, self.backends, self.rows = windows, backends, []

    def _refine(self, sol, a, start, rec, merged=None):
        window = len({r["window"] for r in self.rows})
        if window < self.bench_windows:
            for setting, options in SETTINGS.items():
                for name in self.backends:
                    alloc = self.time_allocation(sol, a, start, rec, merged)
                    problem = self._not_longer(alloc.problem, sol, name)  # the problem the refinement solves
                    f0 = problem.fun(problem.x0)  # cached: not counted below
                    t0 = time.perf_counter()
                    res = nlp.minimize(problem, name, options)
                    dt = time.perf_counter() - t0
                    self.active, self.limit_rows = alloc.base  # as before this backend's run
                    self.rows.append(dict(window=f"{a}..{a + len(sol.durations)}", steps=len(sol.durations),
                                          setting=setting, backend=name, status=res.status.value,
                                          iterations=res.iterations, evaluations=res.evaluations,
                                          gradient_evaluations=res.gradient_evaluations,
                                          points=len(alloc.solved),
                                          nan_points=sum(s is None for s in alloc.solved.values()), time_s=dt,
                                          f_start=f0, objective=res.objective,
                                          best_seen=min(v.cost + alloc.weight * v.durations.sum()
                                                        for v in alloc.solved.values()
                                                        if v is not None and v.durations.sum()
                                                        <= sol.durations.sum() + SAME_LENGTH)))
        return super()._refine(sol, a, start, rec, merged)


def with_baseline(rows: list[dict]) -> list[dict]:
    """Each row's gap and time ratio against Ipopt's row of the same window and setting."""
    base = {(r["window"], r["setting"]): r for r in rows if r["backend"] == BASELINE}
    for r in rows:
        b = base.get((r["window"], r["setting"]))
        if b is not None:
            r["gap_vs_ipopt"] = (r["objective"] - b["objective"]) / abs(b["objective"])
            r["best_gap_vs_ipopt"] = (r["best_seen"] - b["best_seen"]) / abs(b["best_seen"])
            r["time_vs_ipopt"] = r["time_s"] / b["time_s"]
    return rows


def table(rows: list[dict]) -> str:
    head = (f"{'window':>7} {'setting':>9} {'backend':>12} {'status':>18} {'iter':>5} {'f evals':>7} {'g evals':>7} "
            f"{'points':>6} {'NaN':>4} {'time s':>7} {'f start':>9} {'objective':>11} {'gap vs ipopt':>12} "
            f"{'best seen':>11} {'best gap':>9} {'t/t_ipopt':>9}")
    lines = [head, "-" * len(head)]
    for r in rows:
        lines.append(f"{r['window']:>7} {r['setting']:>9} {r['backend']:>12} {r['status']:>18} {r['iterations']:>5} "
                     f"{r['evaluations']:>7} {r['gradient_evaluations']:>7} {r['points']:>6} {r['nan_points']:>4} {r['time_s']:>7.2f} "
                     f"{r['f_start']:>9.2f} {r['objective']:>11.4f} {r.get('gap_vs_ipopt', float('nan')):>+12.2e} "
                     f"{r['best_seen']:>11.4f} {r.get('best_gap_vs_ipopt', float('nan')):>+9.1e} "
                     f"{r.get('time_vs_ipopt', float('nan')):>9.2f}")
    return "\n".join(lines)


def summary(rows: list[dict]) -> str:
    """Per setting and backend: total time, calls and points over the windows, worst gap, optimal statuses."""
    lines = [f"{'setting':>9} {'backend':>12} {'total s':>8} {'f evals':>8} {'points':>7} {'worst gap':>10} "
             f"{'worst best gap':>14} {'ok/windows':>10}"]
    for setting in SETTINGS:
        for name in dict.fromkeys(r["backend"] for r in rows):
            rs = [r for r in rows if r["setting"] == setting and r["backend"] == name]
            if not rs:
                continue
            ok = sum(r["status"] in ("optimal", "optimal_inaccurate") for r in rs)
            lines.append(f"{setting:>9} {name:>12} {sum(r['time_s'] for r in rs):>8.2f} "
                         f"{sum(r['evaluations'] for r in rs):>8} {sum(r['points'] for r in rs):>7} {max(r.get('gap_vs_ipopt', np.nan) for r in rs):>+10.2e} "
                         f"{max(r.get('best_gap_vs_ipopt', np.nan) for r in rs):>+14.2e} "
                         f"{ok:>4}/{len(rs)}")
    return "\n".join(lines)


def benchmarked(config: pathlib.Path, windows: int, backends: list[str]) -> Benchmarked:
    """The receding horizon over ``config``'s discrete plan, refined as ``mrfswarm run --nlp ipopt`` refines it,
    whose first ``windows`` windows' NLPs ``backends`` minimize too."""
    cfg = load_config(config, ["simulation.enabled=false", "smoothing.time_refinement=true",
                               "smoothing.refinement=nlp", f"smoothing.nlp={BASELINE}"])
    discrete = plan(load_config(config, ["simulation.enabled=false", "smoothing.enabled=false"]), progress=False)
    return Benchmarked(discrete.discrete.paths, discrete.scenario.grid, cfg.smoothing, cfg.scenario.robot_radius,
                       cfg.smoothing.backend, qp_options(cfg), workers=1, windows=windows, backends=backends)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--config", type=pathlib.Path, default=ROOT / "experiments" / "corridor.toml")
    ap.add_argument("--windows", type=int, default=4, help="windows benchmarked (the first ones)")
    ap.add_argument("--out", type=pathlib.Path, default=RESULTS)
    args = ap.parse_args(argv)

    backends = nlp.available()
    if BASELINE not in backends:
        raise SystemExit(f"the baseline {BASELINE} is not installed")
    rh = benchmarked(args.config, args.windows, backends)
    print(f"{args.config.name}: {rh.N} robots, {rh.T} steps; QP backend {rh.backend}; NLP backends "
          f"{', '.join(backends)}; load {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    rh.run()
    rows = with_baseline(rh.rows)
    print(table(rows))
    print()
    print(summary(rows))
    write_csv(args.out, rows, COLUMNS, float_format=".6g")
    print(f"\nwrote {args.out}")


if __name__ == "__main__":
    main()
