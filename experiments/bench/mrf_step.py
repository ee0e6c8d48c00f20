"""Time per MRF step, by stage, against a plain per-label Python loop baseline.

For N robots (a Gaussian swarm in free space pulled toward a goal, k = min(7, N - 1))
and search orders n, runs a few planner steps and reports the median time of each stage
(graph, cliques, label sets, energy tables, optimizer) and of the whole step, next to a
baseline step written the plain way (networkx cliques, per-robot per-label Python loops
for label sets and for ICM's local energies), run on the same swarms in the same
process. Beside the times, for reference: how much each lowered the step's energy (median
over the steps, each on its own interaction graph, whose ties among equally near robots
the two may break differently) and on how many steps both moved every robot to the same
cell (the baseline visits the robots in index order, our ICM by colour classes, so the
two may settle in different local minima; 100 robots at n = 2: none of 3 steps alike, the
decreases within 1 %).

    python experiments/bench/mrf_step.py [--sizes 5,10,50,100,500,1000] [--orders 1,2,4,8]
        [--steps 3] [--baseline-max 1000] [--method icm] [--out experiments/bench/results/mrf_step.csv]

With ``--methods [m1,m2,...]`` (default: every installed method of ``solvers.mrf.METHODS``
except the exhaustive ones) it prints instead a table of the MRF methods on the same
step MRFs: for N in ``--method-sizes`` (default 10, 100, 1000; order n = 2, k = 7) and two
fields, the swarm above pulled to its goal (``goal``) and the same swarm without a goal
(``none``, rho_S = 0: the paper's free-space formation, where only the interaction terms
act), the swarm is stepped by ICM for ``--steps`` steps, and on each step's MRF (same
positions for every method) every method runs once with default options (seed 0).
Per N and method: median optimizer time per MRF step, median whole step time (the
method-independent stages, timed once per step, plus the optimizer), the step energy
relative to ICM's on the same MRF (mean over steps, % of |E_icm|; negative = lower; the
goal potential is most of E, so these are small),
the share of ICM's decrease from "everybody stays" that the method achieves (mean,
100 = as ICM), on how many steps it ends below / above ICM, and the gap to the TRW-S
lower bound of the same MRF (mean, % of |LB|). Written to ``--methods-out``.

    python experiments/bench/mrf_step.py --methods [--method-sizes 10,100,1000] [--steps 5]
"""

from __future__ import annotations

import argparse
import csv
import math
import statistics
import time
from pathlib import Path

import networkx as nx
import numpy as np
from scipy.spatial import cKDTree

from mrfswarm.config import GoalPotentialConfig, ObstaclePotentialConfig
from mrfswarm.discrete.motion import MIN_SEPARATION, min_distance_during_move, stencil
from mrfswarm.discrete.planner import STAGES, DiscreteProblem, graph_weights, mrf_step, step_model
from mrfswarm.discrete.potentials import Morse, static_field
from solvers import mrf as mrf_solvers
from solvers.errors import SolverNotFound

RESULTS = Path(__file__).parent / "results"


def swarm(n: int, seed: int = 0) -> DiscreteProblem:
    """N robots on distinct cells, Gaussian around the left of a free map, goal on the right."""
    rng = np.random.default_rng(seed)
    side = max(40, int(6 * math.sqrt(n)))
    W, H = 2 * side, side
    centre = np.array([side // 2, side // 2])
    cells: set[tuple[int, int]] = set()
    sigma = max(2.0, 0.8 * math.sqrt(n))
    while len(cells) < n:
        c = np.round(rng.normal(centre, sigma)).astype(int)
        if 0 <= c[0] < W and 0 <= c[1] < H:
            cells.add((int(c[0]), int(c[1])))
    start = np.array(sorted(cells))
    free = np.ones((W, H), bool)
    goal = np.array([W - side // 2, side // 2])
    # the paper's straight-line field and contested-cell rule, which the plain baseline implements
    static = static_field(np.zeros((W, H)), goal, 1.0, GoalPotentialConfig(distance="euclidean"),
                          ObstaclePotentialConfig())
    return DiscreteProblem(free=free, static=static, start=start, goal=goal, morse=Morse(), k=min(7, n - 1), order=2,
                           contested="nearest")


def baseline_step(problem: DiscreteProblem, pos: np.ndarray) -> tuple[np.ndarray, float, float]:
    """One MRF step written the plain way: loops over robots and labels; the new cells, and the step's energy
    before and after it on the step's graph.

    networkx k-NN graph and cliques; label sets by checking every stencil cell of every
    robot in Python; sequential ICM computing each label's local energy with a Python loop
    over the robot's neighbours and nearby robots. Same rules as the library (disjoint
    label sets, contested cells to the nearer robot, no move closer than one cell).
    """
    N = len(pos)
    free, static, morse, k = problem.free, problem.static, problem.morse, problem.k
    W, H = free.shape
    tree = cKDTree(pos)
    _, idx = tree.query(pos, k + 1)
    g = nx.Graph()
    g.add_nodes_from(range(N))
    for i in range(N):
        for j in idx[i, 1:]:
            g.add_edge(i, int(j))
    cliques = list(nx.find_cliques(g))
    w_node = [0] * N
    w_edge: dict[tuple[int, int], int] = {}
    for c in cliques:
        for i in c:
            w_node[i] += 1
        for a in range(len(c)):
            for b in range(a + 1, len(c)):
                key = (min(c[a], c[b]), max(c[a], c[b]))
                w_edge[key] = w_edge.get(key, 0) + 1
    nbrs: list[list[tuple[int, int]]] = [[] for _ in range(N)]
    for (i, j), w in w_edge.items():
        nbrs[i].append((j, w))
        nbrs[j].append((i, w))
    occupied = {tuple(p) for p in pos.tolist()}
    claims: dict[tuple[int, int], tuple[int, int]] = {}
    for i in range(N):
        for o in stencil(problem.order).tolist():
            c = (pos[i][0] + o[0], pos[i][1] + o[1])
            if not (0 <= c[0] < W and 0 <= c[1] < H) or not free[c]:
                continue
            if c in occupied and o != [0, 0]:
                continue
            d2 = o[0] ** 2 + o[1] ** 2
            if c not in claims or (d2, i) < claims[c]:
                claims[c] = (d2, i)
    labels: list[list[tuple[int, int]]] = [[] for _ in range(N)]
    for c, (_, i) in claims.items():
        labels[i].append(c)
    near = [[j for j in tree.query_ball_point(pos[i], 2 * math.sqrt(problem.order) + 1) if j != i] for i in range(N)]
    x = [tuple(p) for p in pos.tolist()]
    changed = True
    while changed:
        changed = False
        for i in range(N):
            best, best_e = x[i], None
            for c in labels[i]:
                ok = True
                for j in near[i]:
                    d0 = np.array(pos[i] - pos[j], float)
                    v = np.array(c, float) - pos[i] - (np.array(x[j], float) - pos[j])
                    if min_distance_during_move(d0, v) < MIN_SEPARATION - 1e-9:
                        ok = False
                        break
                if not ok:
                    continue
                e = w_node[i] * static[c]
                for j, w in nbrs[i]:
                    e += w * morse(math.hypot(c[0] - x[j][0], c[1] - x[j][1]))
                if best_e is None or e < best_e - 1e-12 or (c == x[i] and e <= best_e + 1e-12):
                    best, best_e = c, e
            if best != x[i]:
                x[i] = best
                changed = True
    new = np.array(x)

    def energy(cells: np.ndarray) -> float:
        return float(sum(w_node[i] * static[tuple(cells[i])] for i in range(N)) + sum(
            w * morse(math.hypot(*(cells[i] - cells[j]))) for (i, j), w in w_edge.items()))

    return new, energy(pos), energy(new)


def write_csv(rows: list[dict], path: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    print(f"wrote {path}")


def methods_table(methods: list[str], sizes: list[int], steps: int, out: Path, order: int = 2, k: int = 7) -> None:
    """Every method on the same step MRFs of an ICM-driven swarm; see the module docstring."""
    if "icm" not in methods:
        methods = ["icm", *methods]
    if "trws" not in methods:
        raise SystemExit("--methods needs trws for the lower bound column")
    rows = []
    print(f"MRF methods on the same step MRFs (order n = {order}, k = min({k}, N - 1), {steps} ICM-driven steps; "
          "medians over steps, energies means over steps)")
    print(f"{'N':>5} {'field':>5} {'method':>13} {'opt ms':>9} {'step ms':>9} {'E vs ICM %':>11} "
          f"{'decrease %ICM':>13} {'below/above':>11} {'LB gap %':>9} {'iters':>6}")
    for n_rob, field in [(n, f) for n in sizes for f in ("goal", "none")]:
        base = swarm(n_rob)
        problem = DiscreteProblem(**{**base.__dict__, "order": order, "k": min(k, n_rob - 1)})
        if field == "none":
            problem = DiscreteProblem(**{**problem.__dict__, "goal": None, "static": np.zeros_like(problem.static)})
        pos = problem.start
        per: dict[str, dict[str, list]] = {m: {"t": [], "e": [], "it": []} for m in methods}
        shared_t, stay_e, lbs, sizes_ec = [], [], [], []
        for _ in range(steps):
            t0 = time.perf_counter()
            weights = graph_weights(pos, problem.k)
            labels, model = step_model(problem, pos, weights)
            shared_t.append(time.perf_counter() - t0)
            stay_e.append(model.energy(model.initial))
            sizes_ec.append((len(model.edges), len(model.conflicts)))
            results = {}
            for m in methods:
                res = mrf_solvers.minimize(model, m, mrf_solvers.Options(seed=0))
                results[m] = res
                per[m]["t"].append(res.time_s)
                per[m]["e"].append(res.energy)
                per[m]["it"].append(res.iterations)
            lbs.append(results["trws"].lower_bound)
            pos = pos + labels.offsets[np.arange(len(pos)), results["icm"].labels]
        e_icm = np.array(per["icm"]["e"])
        stay = np.array(stay_e)
        lb = np.array(lbs, dtype=float)
        for m in methods:
            e = np.array(per[m]["e"])
            rel = 100 * (e - e_icm) / np.abs(e_icm)
            dec = np.where(stay - e_icm > 0, 100 * (stay - e) / np.where(stay - e_icm > 0, stay - e_icm, 1), np.nan)
            tol = 1e-9 * np.maximum(1.0, np.abs(e_icm))
            below, above = int(np.sum(e < e_icm - tol)), int(np.sum(e > e_icm + tol))
            gap = 100 * (e - lb) / np.abs(lb)
            opt_ms = statistics.median(per[m]["t"]) * 1e3
            step_ms = statistics.median(np.array(per[m]["t"]) + np.array(shared_t)) * 1e3
            row = {"N": n_rob, "field": field, "n": order, "k": problem.k, "method": m, "optimizer_ms": round(opt_ms, 3),
                   "step_ms": round(step_ms, 3), "energy_vs_icm_pct": float(rel.mean()),
                   "decrease_vs_icm_pct": float(np.nanmean(dec)) if np.isfinite(dec).any() else float("nan"),
                   "steps_below_icm": below, "steps_above_icm": above, "lb_gap_pct": float(gap.mean()),
                   "iterations": statistics.median(per[m]["it"]),
                   "edges_mean": float(np.mean([e for e, _ in sizes_ec])),
                   "conflicts_mean": float(np.mean([c for _, c in sizes_ec]))}
            rows.append(row)
            print(f"{n_rob:>5} {field:>5} {m:>13} {opt_ms:>9.2f} {step_ms:>9.2f} {rel.mean():>11.2e} "
                  f"{row['decrease_vs_icm_pct']:>13.2f} {f'{below}/{above}':>11} {gap.mean():>9.2e} "
                  f"{row['iterations']:>6g}", flush=True)
    write_csv(rows, out)


def check_methods(ap: argparse.ArgumentParser, flag: str, names: list[str]) -> None:
    """Exit with one line naming ``flag``'s first unknown or uninstalled method and the installed ones."""
    for name in names:
        try:
            mrf_solvers.METHODS.get(name)
        except SolverNotFound as e:
            raise SystemExit(f"{ap.prog}: error: {flag}: {e}") from None


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", default="5,10,50,100,500,1000")
    ap.add_argument("--orders", default="1,2,4,8")
    ap.add_argument("--steps", type=int, default=3, help="steps timed per cell of the table (median)")
    ap.add_argument("--baseline-max", type=int, default=1000, help="largest N the baseline is run for")
    ap.add_argument("--method", default="icm")
    ap.add_argument("--out", type=Path, default=RESULTS / "mrf_step.csv")
    ap.add_argument("--methods", nargs="?", const="", default=None,
                    help="instead: compare MRF methods (comma-separated; default every installed one but exact)")
    ap.add_argument("--method-sizes", default="10,100,1000", help="N for --methods")
    ap.add_argument("--methods-out", type=Path, default=RESULTS / "mrf_step_methods.csv")
    args = ap.parse_args()
    check_methods(ap, "--method", [args.method])
    if args.methods is not None:
        names = (args.methods.split(",") if args.methods
                 else mrf_solvers.METHODS.available(lambda c: not c.optimal))
        check_methods(ap, "--methods", names)
        methods_table(names, [int(v) for v in args.method_sizes.split(",")], args.steps, args.methods_out)
        return
    sizes = [int(v) for v in args.sizes.split(",")]
    orders = [int(v) for v in args.orders.split(",")]
    rows = []
    head = f"{'N':>5} {'n':>2} {'k':>2} " + " ".join(f"{s:>9}" for s in STAGES) + f" {'total':>9} {'baseline':>9} {'speedup':>7}"
    head += f" {'dE':>10} {'base dE':>10} {'same':>5}"
    print(f"time per MRF step in ms (median of {args.steps} steps), method {args.method}; dE: the step's energy "
          "decrease, ours and the baseline's (median); same: steps whose robots both moved to the same cells")
    print(head)
    for n_rob in sizes:
        for order in orders:
            base = swarm(n_rob)
            problem = DiscreteProblem(**{**base.__dict__, "order": order})
            pos = problem.start
            stage_t = {s: [] for s in STAGES}
            totals, base_t, drops, base_drops, same = [], [], [], [], []
            for _ in range(args.steps):
                t0 = time.perf_counter()
                out = mrf_step(problem, pos, args.method)
                totals.append(time.perf_counter() - t0)
                drops.append(out.energy_before - out.energy_after)
                for s in STAGES:
                    stage_t[s].append(out.timings[s])
                if n_rob <= args.baseline_max:
                    t0 = time.perf_counter()
                    base_pos, before, after = baseline_step(problem, pos)
                    base_t.append(time.perf_counter() - t0)
                    base_drops.append(before - after)
                    same.append(bool(np.array_equal(base_pos, out.positions)))
                pos = out.positions
            med = {s: statistics.median(v) * 1e3 for s, v in stage_t.items()}
            total = statistics.median(totals) * 1e3
            bl = statistics.median(base_t) * 1e3 if base_t else float("nan")
            drop = statistics.median(drops)
            base_drop = statistics.median(base_drops) if base_drops else float("nan")
            row = {"N": n_rob, "n": order, "k": problem.k, **{f"{s}_ms": round(med[s], 3) for s in STAGES},
                   "total_ms": round(total, 3), "baseline_ms": round(bl, 3), "speedup": round(bl / total, 1),
                   "energy_drop": drop, "baseline_energy_drop": base_drop, "same_cells": f"{sum(same)}/{len(same)}"}
            rows.append(row)
            print(f"{n_rob:>5} {order:>2} {problem.k:>2} " + " ".join(f"{med[s]:>9.2f}" for s in STAGES)
                  + f" {total:>9.2f} {bl:>9.1f} {bl / total:>7.1f} {drop:>10.4g} {base_drop:>10.4g}"
                  + f" {row['same_cells']:>5}", flush=True)
    write_csv(rows, args.out)


if __name__ == "__main__":
    main()
