"""Time of each pipeline stage, end to end, for the corridor (5 and 10 robots) and 100 robots.

Stages: discrete (MRF steps), pruning (per execution block, made safe), smoothing
(receding-horizon min-snap QPs), checking (sampled certification at 200 Hz), simulation
(RotorPy, every robot). Targets (issue 4): planning without simulation of the 10-robot
corridor under 2 s, of 100 robots under 30 s. Prints a table and writes CSV. Each row
is one run (the planner is deterministic); ``--repeats`` takes the median.

    python experiments/bench/end_to_end.py [--no-sim] [--repeats 1] [--qp osqp]
        [--out experiments/bench/results/end_to_end.csv]
"""

from __future__ import annotations

import argparse
import csv
import statistics
import time
from pathlib import Path

import mrfswarm
from mrfswarm.pipeline import plan

EXP = Path(__file__).resolve().parents[1]
CASES = [
    ("corridor, 5 robots", "corridor.toml", True),
    ("corridor, 10 robots", "corridor10.toml", True),
    ("free space, 100 robots", "swarm100.toml", False),  # 100 RotorPy flights take minutes: off unless --sim-all
]
STAGES = ("discrete", "pruning", "smoothing", "checking", "simulation")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--no-sim", action="store_true", help="skip the RotorPy simulation everywhere")
    ap.add_argument("--sim-all", action="store_true", help="also simulate the 100-robot swarm")
    ap.add_argument("--repeats", type=int, default=1)
    ap.add_argument("--qp", default=None, help="QP backend (default: the config's, osqp)")
    ap.add_argument("--out", type=Path, default=Path(__file__).parent / "results" / "end_to_end.csv")
    args = ap.parse_args()
    rows = []
    print(f"{'case':<24} {'steps':>5} " + " ".join(f"{s:>10}" for s in STAGES) + f" {'planning':>9} {'total':>8}")
    for name, cfg_name, sim in CASES:
        sim = (sim or args.sim_all) and not args.no_sim
        cfg = mrfswarm.load_config(EXP / cfg_name, [f"simulation.enabled={'true' if sim else 'false'}"])
        runs = []
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            r = plan(cfg, qp=args.qp, progress=False)
            runs.append((time.perf_counter() - t0, r))
        total = statistics.median(t for t, _ in runs)
        r = runs[0][1]
        st = {s: statistics.median(rr.timings_s.get(s, 0.0) for _, rr in runs) for s in STAGES}
        planning = sum(st[s] for s in STAGES if s != "simulation") + r.timings_s.get("scenario", 0.0)
        row = {"case": name, "robots": r.scenario.n_robots, "mrf_steps": r.discrete.n_steps, "qp": r.qp,
               **{f"{s}_s": round(st[s], 3) for s in STAGES}, "planning_s": round(planning, 3),
               "total_s": round(total, 3), "makespan_s": round(r.continuous.makespan_s, 2),
               "min_separation_m": round(r.continuous.check.min_separation, 3), "simulated": sim}
        rows.append(row)
        print(f"{name:<24} {r.discrete.n_steps:>5} " + " ".join(f"{st[s]:>10.2f}" for s in STAGES)
              + f" {planning:>9.2f} {total:>8.2f}", flush=True)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    with open(args.out, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    print(f"seconds per stage; planning = everything but the simulation. wrote {args.out}")


if __name__ == "__main__":
    main()
