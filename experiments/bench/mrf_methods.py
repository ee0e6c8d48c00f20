"""Benchmark every registered MRF method on synthetic swarm-like problems.

For each size N (robots), a few seeds of :func:`solvers.mrf.synthetic.swarm_mrf`
(L = 9 labels: stay or one of 8 neighbour cells; symmetric k-NN edges, E ~ 3.5 N for
k = 6; conflicts between robots within 2.9 cells: same target cell or a swap), every
method in ``solvers.mrf.METHODS`` (``exact`` only where it accepts the size) with default
options; optional variants (``--variants``) with polish / larger flips. Prints

1. per N and method: median wall time of ``minimize`` (setup included), iterations,
   energy relative to ICM on the same instance (mean over seeds, %; negative = better),
   the TRW-S lower bound gap, repairs;
2. vectorized ICM against a plain Python ICM (per node, per label, per incident edge)
   in the same node order: same labelling, time and speed-up.

Writes every row to ``experiments/bench/results/mrf_methods.csv``.

    PYTHONPATH=. python experiments/bench/mrf_methods.py            # ~1 minute
    PYTHONPATH=. python experiments/bench/mrf_methods.py --sizes 10 100 --seeds 5 --variants
"""

from __future__ import annotations

import argparse
import csv
import pathlib
import statistics
import time

import numpy as np

from solvers import mrf
from solvers.errors import InvalidProblem
from solvers.mrf.local_energy import colour_classes
from solvers.mrf.synthetic import swarm_mrf

RESULTS = pathlib.Path(__file__).parent / "results" / "mrf_methods.csv"

VARIANTS = {
    "bp+polish": ("bp", dict(polish=True)),
    "trws+polish": ("trws", dict(polish=True)),
    "gibbs+polish": ("gibbs", dict(polish=True)),
    "gibbs(log)": ("gibbs", dict(schedule="log")),
    "lazy_flipper(3)": ("lazy_flipper", dict(max_flip=3)),
}


def plain_icm(m: mrf.PairwiseMRF, order: np.ndarray, tol: float = 1e-9, max_sweeps: int = 100) -> np.ndarray:
    """ICM written the obvious way: Python loops over nodes, labels and incident pairs."""
    N = m.n_nodes
    inc_e = [[] for _ in range(N)]
    for e, (u, v) in enumerate(m.edges.tolist()):
        inc_e[u].append((e, v, 0))
        inc_e[v].append((e, u, 1))
    inc_c = [[] for _ in range(N)]
    for c, (u, v) in enumerate(m.conflicts.tolist()):
        inc_c[u].append((c, v, 0))
        inc_c[v].append((c, u, 1))
    x = m.initial.tolist()
    n_labels = m.n_labels.tolist()

    def local(i: int, a: int) -> float:
        s = m.unary[i, a]
        for e, j, end in inc_e[i]:
            s += m.pairwise[e, a, x[j]] if end == 0 else m.pairwise[e, x[j], a]
        return s

    def allowed(i: int, a: int) -> bool:
        for c, j, end in inc_c[i]:
            if (m.conflict_mask[c, a, x[j]] if end == 0 else m.conflict_mask[c, x[j], a]):
                return False
        return True

    for _ in range(max_sweeps):
        moved = 0
        for i in order.tolist():
            cur = local(i, x[i])
            best_a, best_v = x[i], cur
            for a in range(n_labels[i]):
                if allowed(i, a):
                    v = local(i, a)
                    if v < best_v:
                        best_a, best_v = a, v
            if best_v < cur - tol:
                x[i] = best_a
                moved += 1
        if moved == 0:
            break
    return np.array(x)


def timed(m: mrf.PairwiseMRF, method: str, options: mrf.Options, budget: float) -> tuple[mrf.MRFResult, float]:
    """Run until ``budget`` seconds are spent (at most 7 runs); the last result and the median time."""
    times = []
    while True:
        res = mrf.minimize(m, method, options)
        times.append(res.time_s)
        if sum(times) >= budget or len(times) >= 7:
            return res, statistics.median(times)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[6, 10, 100, 1000])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--k", type=int, default=6, help="nearest neighbours (E ~ 3.5 N for 6)")
    ap.add_argument("--labels", type=int, default=9)
    ap.add_argument("--variants", action="store_true", help="also run polished / larger-flip variants")
    ap.add_argument("--budget", type=float, default=0.3, help="seconds of repeats per timing")
    ap.add_argument("--out", type=pathlib.Path, default=RESULTS)
    args = ap.parse_args(argv)

    runs = [(name, name, {}) for name in mrf.METHODS.names()]
    if args.variants:
        runs += [(label, name, opts) for label, (name, opts) in VARIANTS.items()]
    rows, base_rows = [], []
    for N in args.sizes:
        for seed in range(args.seeds):
            m = swarm_mrf(N, L=args.labels, k=args.k, seed=seed)
            e_init = m.energy(m.initial)
            icm_energy = None
            for label, name, opts in runs:
                try:
                    res, t = timed(m, name, mrf.Options(**opts), args.budget)
                except InvalidProblem:
                    continue  # exact on a problem too big to enumerate
                if name == "icm" and not opts:
                    icm_energy = res.energy
                rows.append(dict(N=N, seed=seed, E=len(m.edges), C=len(m.conflicts), L=m.max_labels, method=label,
                                 time_ms=1e3 * t, iterations=res.iterations, energy=res.energy,
                                 initial_energy=e_init, icm_energy=icm_energy,
                                 rel_icm_pct=100 * (res.energy - icm_energy) / abs(icm_energy),
                                 lower_bound=res.lower_bound, repaired=res.repaired,
                                 repairs=res.stats.get("repairs", 0)))
            order = np.concatenate(colour_classes(m))
            t0 = time.perf_counter()
            ref = plain_icm(m, order)
            t_loop = time.perf_counter() - t0
            res, t_vec = timed(m, "icm", mrf.Options(), args.budget)
            base_rows.append(dict(N=N, seed=seed, vec_ms=1e3 * t_vec, loop_ms=1e3 * t_loop,
                                  same=bool(np.array_equal(ref, res.labels))))

    print(f"swarm-like MRFs, L={args.labels}, k={args.k}, {args.seeds} seeds per size; "
          "time = median ms per minimize; rel = energy vs ICM on the same instance (mean %, <0 better)")
    print(f"{'N':>5} {'E':>5} {'C':>5} {'method':<16} {'time ms':>9} {'iters':>6} {'rel ICM %':>10} "
          f"{'worst %':>8} {'bound gap %':>11} {'repaired':>8}")
    for N in args.sizes:
        for label, _, _ in runs:
            rs = [r for r in rows if r["N"] == N and r["method"] == label]
            if not rs:
                continue
            gap = ""
            if rs[0]["lower_bound"] is not None:
                best = [min(q["energy"] for q in rows if q["N"] == N and q["seed"] == r["seed"]) for r in rs]
                gap = f"{statistics.mean(100 * (b - r['lower_bound']) / abs(b) for b, r in zip(best, rs)):.3f}"
            print(f"{N:>5} {rs[0]['E']:>5} {rs[0]['C']:>5} {label:<16} "
                  f"{statistics.median(r['time_ms'] for r in rs):>9.2f} "
                  f"{statistics.median(r['iterations'] for r in rs):>6.0f} "
                  f"{statistics.mean(r['rel_icm_pct'] for r in rs):>10.3f} "
                  f"{max(r['rel_icm_pct'] for r in rs):>8.3f} {gap:>11} "
                  f"{sum(r['repaired'] for r in rs):>8}")
    print("\n(bound gap: best energy found by any method vs the TRW-S / exact lower bound)")
    print("\nvectorized ICM vs plain Python-loop ICM (same node order)")
    print(f"{'N':>5} {'vec ms':>9} {'loop ms':>10} {'speed-up':>9} {'same labels':>12}")
    for N in args.sizes:
        bs = [b for b in base_rows if b["N"] == N]
        v = statistics.median(b["vec_ms"] for b in bs)
        lo = statistics.median(b["loop_ms"] for b in bs)
        print(f"{N:>5} {v:>9.2f} {lo:>10.1f} {lo / v:>9.1f} {str(all(b['same'] for b in bs)):>12}")

    args.out.parent.mkdir(parents=True, exist_ok=True)
    with args.out.open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]) + ["icm_loop_ms", "icm_loop_same"])
        w.writeheader()
        for r in rows:
            b = next(b for b in base_rows if b["N"] == r["N"] and b["seed"] == r["seed"])
            w.writerow({**r, "icm_loop_ms": b["loop_ms"] if r["method"] == "icm" else "",
                        "icm_loop_same": b["same"] if r["method"] == "icm" else ""})
    print(f"\nwrote {args.out}")


if __name__ == "__main__":
    main()
