"""The continuous stage end to end, per scenario and variant, against the code it replaced.

Variants (all without the quadrotor simulation):

- ``tube (before)``: the continuous stage of git revision ``--baseline`` (default
  ``be04db8``, before safe regions: a sampled tube around a reference at rest at every
  step, rest seams), run from that revision's code in a child process of the same
  session. That code rejects the config keys it does not know (the paper's scenario configs
  now set ``mrf.follow`` and the later rules back to the paper's): the keys its config lacks
  are dropped for it (``baseline_code.drop_unknown_keys``; the corridor flew 69.57 s, 16 stops per robot,
  snap 29,396, as the README's "before" column, 2026-11-29);
- ``paper seams``: safe regions with the paper's receding horizon (4 steps planned, 50 %
  executed, at rest at every seam);
- ``default``: the config's own continuous stage (by default safe regions, 8 steps planned,
  50 % executed, continuous up to jerk);
- ``refined``: the default with ``smoothing.time_refinement = true``, i.e. each window's step
  durations shortened by the multiplier scaling (the default refinement,
  ``smoothing.refinement = "scaling"``: a few QP solves per window), not by an NLP;
- ``refined_nlp``: refined by the NLP instead (``smoothing.refinement = "nlp"``, solved by
  ``smoothing.nlp``, Ipopt by default).

Every variant plans with the paper's discrete rules of ``PAPER_DISCRETE`` (Euclidean goal
field, Gamma = 5, contested cells to the nearest robot, patience on the swarm energy, no trimmed
label sets); the other rules beyond the paper (``mrf.follow``, ``arrival``, ``merge_waits``,
``drop_loops``, ``straighten``) are the case's config's: the paper's scenario configs set them
back, swarm100 keeps the defaults. The variants of the working tree fly the same discrete
paths. Per run, measured from the trajectories by the same code for every variant: makespan,
``makespan_over_flown`` (over the longest path a robot flies, at v_max: a bound of that flight,
not result.json's ``makespan_over_bound``, which needs the working tree's free-path search), full stops (speed below
0.05 m/s and back up inside the flight; max and mean per robot), the integral of squared
snap summed over robots, the smallest separation and obstacle clearance (sampled at
200 Hz), the exact maxima of v, a, j; and seconds: the discrete stage, the continuous
stage (regions or pruning, smoothing, checking) and the paper's waypoint pruning.

Targets (issue 9) at v 2, a 4, j 4: corridor makespan <= 35 s, no stop, snap <= 1,500,
continuous stage <= 2 s; swarm100 makespan <= 150 s, planning no slower than before.

    python experiments/bench/end_to_end.py [--cases corridor,corridor10,blocks,blocks12,swarm100]
        [--variants tube,paper,default,refined,refined_nlp] [--baseline be04db8]
        [--out experiments/bench/results/end_to_end.csv]
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from baseline_code import drop_unknown_keys, extract, run_child, use

EXP = Path(__file__).resolve().parents[1]
RESULTS = Path(__file__).parent / "results"
VARIANTS = {
    "tube": ("tube (before)", []),
    "paper": ("paper seams", ['smoothing.seam="rest"', "smoothing.horizon=4", "smoothing.execution=0.5"]),
    "default": ("default", []),
    "refined": ("refined", ["smoothing.time_refinement=true"]),
    "refined_nlp": ("refined (Ipopt)", ["smoothing.time_refinement=true", 'smoothing.refinement="nlp"']),
}
#: The paper's discrete rules, for every variant: the discrete paths are the same for the code
#: before and now, so the table compares continuous stages only.
PAPER_DISCRETE = {("goal_potential", "distance"): '"euclidean"', ("mrf", "contested"): '"nearest"',
                  ("mrf", "progress"): '"energy"', ("obstacle_potential", "gamma"): "5.0",
                  ("mrf", "trim_backward"): "false"}


def working_tree_flight_quality():
    """The working tree's :mod:`mrfswarm.flight_quality` (one stop count for every variant, whichever code planned)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("fq", Path(__file__).resolve().parents[2] / "mrfswarm" / "flight_quality.py")
    fq = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(fq)
    return fq


def measure(trajectories, grid, v_max: float) -> dict:
    """Flight metrics of trajectories on one time grid (the same code for every variant)."""
    import numpy as np

    try:
        from mrfswarm.continuous.sampled_check import min_pair_distance
    except ImportError:  # the baseline revision's layout
        from mrfswarm.continuous_check import min_pair_distance
    from mrfswarm.metrics import obstacle_clearance
    from mrfswarm.trajectory import integral_squared_derivative, max_derivative_norms

    T = max(tr.duration for tr in trajectories)
    t = np.linspace(0.0, T, int(T * 200) + 1)
    pos = np.stack([tr.evaluate(t) for tr in trajectories], axis=1)
    speed = np.stack([np.linalg.norm(tr.evaluate(t, 1), axis=-1) for tr in trajectories], axis=1)
    stops = working_tree_flight_quality().stops_in_speeds(speed).tolist()
    lengths = np.linalg.norm(np.diff(pos, axis=0), axis=-1).sum(axis=0)
    clr = obstacle_clearance(grid.occupied, (pos.reshape(-1, 2) - np.asarray(grid.origin)) / grid.resolution)
    return {
        "makespan_s": round(float(T), 2),
        "makespan_over_flown": round(float(T / (lengths.max() / v_max)), 2),
        "stops_max": max(stops),
        "stops_mean": round(float(np.mean(stops)), 1),
        "snap_integral": round(float(sum(integral_squared_derivative(tr, 4) for tr in trajectories)), 1),
        "min_separation_m": round(float(min_pair_distance(pos)[0].min()), 3),
        "min_clearance_m": None if clr is None else round(clr * grid.resolution, 3),
        "v_a_j_max": [round(float(max_derivative_norms(trajectories, k).max()), 2) for k in (1, 2, 3)],
    }


def child(case: str, variant: str, code: str | None) -> None:
    """Plan one case with one variant and print its row as JSON (run in a child process)."""
    use(code)
    import tomllib

    from mrfswarm.config import from_dict
    from mrfswarm.pipeline import plan

    data = tomllib.loads((EXP / f"{case}.toml").read_text())
    for section, key in PAPER_DISCRETE:  # the code before knew only the paper's rules: drop them there
        data.get(section, {}).pop(key, None)
    if code:  # and none of the keys added since (mrf.follow, ...), which the configs now set to the paper's rules
        drop_unknown_keys(data)
    extra = [] if code else [f"{section}.{key}={value}" for (section, key), value in PAPER_DISCRETE.items()]
    from mrfswarm.config import apply_overrides

    data = apply_overrides(data, ["simulation.enabled=false", *extra, *VARIANTS[variant][1]])
    cfg = from_dict(data, EXP)
    t0 = time.perf_counter()
    r = plan(cfg, progress=False)
    total = time.perf_counter() - t0
    c, ts = r.continuous, r.timings_s
    continuous = sum(ts.get(k, 0.0) for k in ("regions", "smoothing", "checking"))
    paper_pruning = ts.get("pruning", 0.0)
    if variant == "tube":  # before: pruning was part of the continuous stage
        continuous += paper_pruning
        paper_pruning = 0.0
    row = {"case": case, "variant": VARIANTS[variant][0], "robots": r.scenario.n_robots, "mrf_steps": r.discrete.n_steps,
           **measure(c.trajectories, r.scenario.grid, cfg.smoothing.v_max),
           "discrete_s": round(ts.get("discrete", 0.0), 2), "continuous_s": round(continuous, 2),
           "paper_pruning_s": round(paper_pruning, 2), "total_s": round(total, 2)}
    print(json.dumps(row))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cases", default="corridor,corridor10,blocks,blocks12,swarm100")
    ap.add_argument("--variants", default=",".join(VARIANTS))
    ap.add_argument("--baseline", default="be04db8", help="git revision of the code before safe regions")
    ap.add_argument("--out", type=Path, default=RESULTS / "end_to_end.csv")
    ap.add_argument("--child", nargs=2, metavar=("CASE", "VARIANT"), help=argparse.SUPPRESS)
    ap.add_argument("--code", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        child(*args.child, args.code)
        return
    variants = args.variants.split(",")
    rows = []
    cols = ["makespan_s", "makespan_over_flown", "stops_max", "snap_integral", "min_separation_m", "min_clearance_m",
            "discrete_s", "continuous_s"]
    width = max(len(c) for c in cols)
    print(f"{'case':<11} {'variant':<14} " + " ".join(f"{c:>{width}}" for c in cols))
    with tempfile.TemporaryDirectory() as tmp:
        old = extract(args.baseline, Path(tmp)) if "tube" in variants else None
        for case in args.cases.split(","):
            for v in variants:
                row = run_child(Path(__file__), ["--child", case, v], old if v == "tube" else None)
                rows.append(row)
                print(f"{case:<11} {row['variant']:<14} " + " ".join(f"{str(row[c]):>{width}}" for c in cols),
                      flush=True)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    with open(args.out, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        for row in rows:
            w.writerow({k: json.dumps(v) if isinstance(v, list) else v for k, v in row.items()})
    print(f"continuous_s: regions (or, before, pruning), smoothing and checking; wrote {args.out}")


if __name__ == "__main__":
    main()
