"""Flying a swarm in RotorPy: the batched backend against one simulation per robot.

Plans ``experiments/swarm100.toml`` (100 robots, smoothing on, simulation off) once, then
flies the trajectories: the first ``--subset`` robots with the ``processes`` backend (one
``Multirotor`` per robot in parallel processes, the baseline; for all 100 robots it takes
most of an hour here, so its time is extrapolated linearly from the subset and marked
so), and all robots with the ``batched`` backend (RotorPy's ``BatchedMultirotor``, torch
on the CPU, whose cost per control step hardly depends on the number of robots). Per run: robots, flown seconds, wall seconds,
real-time factor (flown / wall), maximum tracking error and the linear-model bound.
Needs ``pip install "mrfswarm[batched]"``.

    python experiments/bench/flight.py [--subset 2] [--workers 2] [--out experiments/bench/results/flight.csv]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from csv_table import write_csv

import mrfswarm
from mrfswarm.pipeline import plan
from mrfswarm.simulation import fly_swarm

EXP = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--subset", type=int, default=2)
    ap.add_argument("--workers", type=int, default=None, help="processes of the per-robot backend (default: cores)")
    ap.add_argument("--out", type=Path, default=Path(__file__).parent / "results" / "flight.csv")
    args = ap.parse_args()
    t0 = time.perf_counter()
    r = plan(mrfswarm.load_config(EXP / "swarm100.toml", ["simulation.enabled=false"]), progress=False)
    print(f"planned {r.scenario.n_robots} robots in {time.perf_counter() - t0:.1f} s, "
          f"makespan {r.continuous.makespan_s:.1f} s")
    trs, alt, grid, jerk = r.continuous.trajectories, r.config.scenario.altitude, r.scenario.grid, r.continuous.j_max
    speed = r.continuous.v_max
    rows = []
    print(f"{'backend':>10} {'robots':>6} {'flown s':>8} {'wall s':>8} {'x real time':>11} {'max err m':>9} "
          f"{'bound m':>8}")
    runs = [("processes", trs[:args.subset]), ("batched", trs)]
    for backend, group in runs:
        t0 = time.perf_counter()
        f = fly_swarm(group, alt, grid, r.config.simulation.rate_hz, workers=args.workers, jerk=jerk, speed=speed,
                      progress=False, backend=backend)
        wall = time.perf_counter() - t0
        flown = float(f.flights[0].times[-1])
        row = {"backend": backend, "robots": len(group), "flown_s": round(flown, 2), "wall_s": round(wall, 2),
               "real_time_factor": round(flown / wall, 3), "max_tracking_error_m": round(f.max_tracking_error, 4),
               "tracking_bound_m": round(f.tracking_bound, 4), "extrapolated": False}
        rows.append(row)
        print(f"{backend:>10} {len(group):>6} {flown:>8.1f} {wall:>8.1f} {flown / wall:>11.3f} "
              f"{f.max_tracking_error:>9.4f} {f.tracking_bound:>8.4f}", flush=True)
    per_robot = rows[0]["wall_s"] / rows[0]["robots"]
    est = per_robot * len(trs)
    rows.append({**rows[0], "robots": len(trs), "wall_s": round(est, 1),
                 "real_time_factor": round(rows[0]["flown_s"] / est, 3), "max_tracking_error_m": "",
                 "tracking_bound_m": "", "extrapolated": True})
    print(f"{'processes':>10} {len(trs):>6} {rows[0]['flown_s']:>8.1f} {est:>8.1f} {rows[0]['flown_s'] / est:>11.3f}"
          "   (extrapolated from the subset)")
    write_csv(args.out, rows)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
