"""MRF step time in 2-D and in 3-D (voxels, downwash), in one run.

For N robots (default 1000) a Gaussian swarm on a free map pulled toward a goal across
it: in 2-D on a (2s x s) grid, in 3-D on a (2s x s x s/2) voxel grid with the robots at
least one cell apart in the downwash-scaled metric (c = ``--downwash``, default 2: no
two robots in one column closer than c voxels). Both Gaussians have the same peak
density, 0.25 robots per cell (the 2-D one of ``mrf_step.py``, sigma = 0.8 sqrt(N)). Both swarms take the same number of
planner steps from their start; each step is timed whole (interaction graph, cliques,
label sets, energy tables, optimizer), the two dimensions interleaved, and the table
gives the median per stage and in total, and the ratio 3-D / 2-D. The target of issue 20
is a 3-D step within 2 x the 2-D one at N = 1000.

3-D runs with the label-set order of the 2-D run (n = 2: 18 moves in 3-D, 8 in 2-D) and
with n = 3 (the whole 26-neighbourhood, the analogue of the plane's 8).

    python experiments/bench/mrf_step_3d.py [--sizes 1000] [--steps 6] [--repeats 3] [--downwash 2]
        [--method icm] [--out experiments/bench/results/mrf_step_3d.csv]
"""

from __future__ import annotations

import argparse
import csv
import math
import statistics
import time
from pathlib import Path

import numpy as np
from mrf_step import check_methods

from mrfswarm.config import GoalPotentialConfig, ObstaclePotentialConfig
from mrfswarm.discrete.planner import STAGES, DiscreteProblem, graph_weights, mrf_step, problem_label_sets
from mrfswarm.discrete.potentials import Morse, static_field

RESULTS = Path(__file__).parent / "results"


def swarm(n: int, ndim: int, order: int, downwash: float, seed: int = 0) -> DiscreteProblem:
    """N robots in a Gaussian cluster on the left of a free map, the goal on the right."""
    rng = np.random.default_rng(seed)
    if ndim == 2:
        side = max(40, int(6 * math.sqrt(n)))
        shape: tuple[int, ...] = (2 * side, side)
        sigma = max(2.0, 0.8 * math.sqrt(n))
    else:
        side = max(20, int(4 * n ** (1 / 3)))
        shape = (2 * side, side, max(8, side // 2))
        # the 2-D swarm's peak density, N / (2 pi sigma^2) = 0.25 robots per cell, per voxel
        sigma = max(2.0, (0.25 * (2 * math.pi) ** 1.5) ** (-1 / 3) * n ** (1 / 3))
    centre = np.array([side // 2, side // 2] + ([shape[2] // 2] if ndim == 3 else []))
    cells: list[np.ndarray] = []
    taken: set[tuple[int, ...]] = set()
    gap = int(math.ceil(downwash)) if ndim == 3 else 1
    while len(cells) < n:
        c = np.round(rng.normal(centre, sigma)).astype(int)
        if np.any(c < 0) or np.any(c >= shape):
            continue
        column = [tuple(c[:2]) + ((int(c[2]) + dz,) if ndim == 3 else ()) for dz in range(-gap + 1, gap)]
        if any(cell in taken for cell in column):  # one cell apart in the downwash-scaled metric
            continue
        taken.add(tuple(int(v) for v in c))
        cells.append(c)
    start = np.array(sorted(taken))
    goal = np.array(shape) // 2
    goal[0] = shape[0] - side // 2
    static = static_field(np.zeros(shape), goal, 1.0, GoalPotentialConfig(distance="euclidean"),
                          ObstaclePotentialConfig())
    return DiscreteProblem(free=np.ones(shape, bool), static=static, start=start, goal=goal, morse=Morse(),
                           k=min(7, n - 1), order=order, downwash=downwash if ndim == 3 else 1.0)


def step_times(problem: DiscreteProblem, steps: int, method: str) -> list[dict[str, float]]:
    """Per step: the time of every stage and of the whole step (seconds)."""
    pos = problem.start.copy()
    out = []
    for _ in range(steps):
        t0 = time.perf_counter()
        gt: dict[str, float] = {}
        w = graph_weights(pos, problem.k, gt)
        res = mrf_step(problem, pos, method, None, w, gt)
        total = time.perf_counter() - t0
        out.append({**{s: res.timings[s] for s in STAGES}, "total": total})
        pos = res.positions
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", default="1000")
    ap.add_argument("--steps", type=int, default=6)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--downwash", type=float, default=2.0)
    ap.add_argument("--method", default="icm")
    ap.add_argument("--out", type=Path, default=RESULTS / "mrf_step_3d.csv")
    args = ap.parse_args()
    check_methods(ap, "--method", [args.method])
    rows = []
    for n in (int(s) for s in args.sizes.split(",")):
        cases = {"2-D n=2": swarm(n, 2, 2, 1.0), "3-D n=2": swarm(n, 3, 2, args.downwash),
                 "3-D n=3": swarm(n, 3, 3, args.downwash)}
        times: dict[str, list[dict[str, float]]] = {name: [] for name in cases}
        label_counts = {name: problem_label_sets(p, p.start).count for name, p in cases.items()}
        for _ in range(args.repeats):  # interleaved, so that load on the machine hits every case alike
            for name, problem in cases.items():
                times[name] += step_times(problem, args.steps, args.method)
        base = statistics.median(t["total"] for t in times["2-D n=2"])
        base_min = min(t["total"] for t in times["2-D n=2"])
        for name, ts in times.items():
            row = {"n_robots": n, "case": name, "downwash": cases[name].downwash,
                   "labels_max": int(label_counts[name].max()), "labels_mean": float(label_counts[name].mean()),
                   **{s: statistics.median(t[s] for t in ts) for s in (*STAGES, "total")},
                   "total_min": min(t["total"] for t in ts)}
            row["ratio_to_2d"] = row["total"] / base
            row["ratio_min_to_2d"] = row["total_min"] / base_min
            rows.append(row)
    header = ["n_robots", "case", "downwash", "labels_max", "labels_mean", *STAGES, "total", "total_min",
              "ratio_to_2d", "ratio_min_to_2d"]
    print("median seconds per stage and step; min: the fastest step (least disturbed by other load)")
    print(f"{'N':>6} {'case':>9} {'c':>4} {'L':>3} " + " ".join(f"{s:>9}" for s in (*STAGES, "total", "min"))
          + "  3-D/2-D (median, min)")
    for r in rows:
        print(f"{r['n_robots']:>6} {r['case']:>9} {r['downwash']:>4g} {r['labels_max']:>3} "
              + " ".join(f"{1e3 * r[s]:>7.2f}ms" for s in (*STAGES, "total", "total_min"))
              + f"  {r['ratio_to_2d']:.2f}, {r['ratio_min_to_2d']:.2f}")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    with open(args.out, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=header)
        w.writeheader()
        w.writerows(rows)


if __name__ == "__main__":
    main()
