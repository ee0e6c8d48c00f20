"""One MRF step, old code against new: time per stage and identical results, in one session.

For N robots (the swarm of ``mrf_step.py``: Gaussian, free map, goal to the right;
k = 7, order n = 2), a child process imports ``mrfswarm`` either from the working tree
or from the code of git revision ``--ref`` (default ``main``), makes ``--warmup`` steps,
then times ``--steps`` steps (graph, cliques, labels, energy tables, optimizer, and the
whole step) and hashes the positions after every step. As in ``plan_discrete``, each
step's graph (k-NN edges and cliques) is built after the step before, from that step's
graph when the code can (the new code updates the cliques of the robots whose neighbours
changed); its time counts in the step. Children of the two codes
alternate for ``--rounds`` rounds (the machine is shared; alternating spreads the load
over both). The table gives the median and the minimum per stage over all timed steps,
and the script fails unless both codes moved every robot to the same cell at every step.

    python experiments/bench/mrf_step_compare.py [--sizes 1000] [--steps 20] [--rounds 3] [--ref main]
        [--out experiments/bench/results/mrf_step_compare.csv]
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from baseline_code import extract, run_child, use
from csv_table import write_csv

RESULTS = Path(__file__).parent / "results"
PARTS = ("graph", "cliques", "labels", "energy", "optimizer", "step")


def child(n: int, k: int, order: int, warmup: int, steps: int, code: str | None) -> None:
    use(code)
    import inspect

    from mrf_step import swarm

    from mrfswarm.discrete.planner import DiscreteProblem, graph_weights, mrf_step

    base = swarm(n)
    problem = DiscreteProblem(**{**base.__dict__, "order": order, "k": min(k, n - 1)})
    # as plan_discrete does: the graph of the new positions is built after each step, from
    # the previous graph where the code knows how
    incremental = "previous" in inspect.signature(graph_weights).parameters

    def graph(pos, previous, gt):
        return graph_weights(pos, problem.k, gt, previous=previous) if incremental else graph_weights(pos, problem.k, gt)

    pos = problem.start
    gt: dict[str, float] = {}
    weights = graph(pos, None, gt)
    times: dict[str, list[float]] = {p: [] for p in PARTS}
    digest = hashlib.sha256()
    for t in range(warmup + steps):
        t0 = time.perf_counter()
        out = mrf_step(problem, pos, weights=weights, graph_timings=gt)
        pos = out.positions
        gt = {}
        weights = graph(pos, weights, gt)
        if t < warmup:
            continue
        times["step"].append(time.perf_counter() - t0)
        for p in PARTS[:-1]:
            times[p].append((gt if p in ("graph", "cliques") else out.timings)[p])
        digest.update(np.ascontiguousarray(pos, dtype=np.int64).tobytes())
        digest.update(np.float64(out.energy_after).tobytes())
    print(json.dumps({"times": times, "digest": digest.hexdigest()}))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", default="1000")
    ap.add_argument("--k", type=int, default=7)
    ap.add_argument("--order", type=int, default=2)
    ap.add_argument("--warmup", type=int, default=5)
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--ref", default="main")
    ap.add_argument("--out", type=Path, default=RESULTS / "mrf_step_compare.csv")
    ap.add_argument("--child", type=int, help=argparse.SUPPRESS)
    ap.add_argument("--code", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child is not None:
        child(args.child, args.k, args.order, args.warmup, args.steps, args.code)
        return
    rows = []
    print(f"ms per MRF step (k = {args.k}, n = {args.order}; {args.rounds} x {args.steps} steps per code; "
          f"median / min), old = {args.ref}")
    print(f"{'N':>5} {'code':>5} " + " ".join(f"{p:>15}" for p in PARTS))
    with tempfile.TemporaryDirectory() as tmp:
        old = extract(args.ref, Path(tmp))
        for n in (int(v) for v in args.sizes.split(",")):
            acc = {c: {p: [] for p in PARTS} for c in ("old", "new")}
            digests = set()
            for _ in range(args.rounds):
                for name, code in (("new", None), ("old", old)):
                    r = run_child(Path(__file__), ["--child", str(n), "--k", str(args.k), "--order", str(args.order),
                                                   "--warmup", str(args.warmup), "--steps", str(args.steps)], code)
                    for p in PARTS:
                        acc[name][p] += r["times"][p]
                    digests.add(r["digest"])
            if len(digests) != 1:
                raise SystemExit(f"N={n}: the old and the new code moved the robots differently")
            for name in ("old", "new"):
                med = {p: 1e3 * float(np.median(acc[name][p])) for p in PARTS}
                mn = {p: 1e3 * float(np.min(acc[name][p])) for p in PARTS}
                rows.append({"N": n, "code": name, "ref": args.ref if name == "old" else "working tree",
                             **{f"{p}_median_ms": round(med[p], 3) for p in PARTS},
                             **{f"{p}_min_ms": round(mn[p], 3) for p in PARTS}, "identical_paths": True})
                print(f"{n:>5} {name:>5} " + " ".join(f"{med[p]:>7.2f}/{mn[p]:>7.2f}" for p in PARTS), flush=True)
            o, w = rows[-2], rows[-1]
            print(f"{'':>5} {'ratio':>5} " + " ".join(
                f"{o[f'{p}_median_ms'] / max(w[f'{p}_median_ms'], 1e-9):>15.2f}" for p in PARTS) + "  (old / new)")
    write_csv(args.out, rows)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
