"""How much of the default flight's time goes to the shared time grid: what per-robot timing could gain.

All robots fly one common time grid (:mod:`mrfswarm.continuous.regions`: the relative safe
corridors hold between pieces of the same interval), so every step lasts what its slowest
mover needs: a robot starting, stopping or turning slows the whole swarm for that step. Per
case of ``flight_quality.py`` (its maps and settings, the working tree's code), from the
discrete plan and the bold speed profile of the default time grid (``PROFILES[0]`` of
:mod:`mrfswarm.continuous.receding_horizon`), all over the makespan's lower bound:

- ``flown``: the default flight, planned here (the continuous stage, simulation off);
- ``shared``: the bold profile on the common grid (each step its slowest mover's need),
  what the default flies where every window accepts its bold attempt;
- ``own``: the slowest robot flying its own moves on the same profile with no shared grid
  (each robot its own need per step), a bound on what per-robot timing could reach with these
  discrete paths and this profile;
- ``path``: the longest discrete path at v_max (the discrete plan's own share).

    python experiments/bench/timing_headroom.py [--cases corridor,...] [--out F.csv]
"""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from flight_quality import DEFAULT_CASES, RESULTS, case_config


def measure(case: str) -> dict:

    from mrfswarm.config import apply_overrides, from_dict
    from mrfswarm.continuous.receding_horizon import PROFILES, drift_room, motion_acceleration
    from mrfswarm.continuous.time_grid import motion_profile, robot_needs
    from mrfswarm.flight_quality import makespan_lower_bound
    from mrfswarm.pipeline import plan

    data, base = case_config(case)
    cfg = from_dict(apply_overrides(data, ["simulation.enabled=false"]), base)
    r = plan(cfg, progress=False)
    scn, sm = r.scenario, cfg.smoothing
    res = scn.grid.resolution
    paths = r.discrete.paths
    d = scn.distances
    bound = makespan_lower_bound(scn.grid.free, paths[0], paths[-1], res, sm.v_max, None if d is None else d.path)
    _, cruise, acc = PROFILES[0]
    a = motion_acceleration(sm.v_max, sm.a_max, sm.j_max, acc)
    drift = drift_room(res, cfg.scenario.robot_radius)
    need, length = robot_needs(paths, res, cruise * sm.v_max, a, drift)
    shared = motion_profile(paths, res, cruise * sm.v_max, a, drift).durations.sum()
    flown = float(r.smoothed().knot_times[-1])
    return {"case": case, "robots": paths.shape[1], "steps": len(paths) - 1, "bound_s": round(bound, 2),
            "flown": round(flown / bound, 2), "shared": round(shared / bound, 2),
            "own": round(float(need.sum(axis=0).max()) / bound, 2),
            "path": round(float(length.sum(axis=0).max()) / sm.v_max / bound, 2)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", default=DEFAULT_CASES)
    ap.add_argument("--out", type=Path, default=RESULTS / "timing_headroom.csv")
    args = ap.parse_args()
    rows = [measure(case) for case in args.cases.split(",")]
    keys = list(rows[0])
    print("  ".join(f"{k:>9}" for k in keys))
    for row in rows:
        print("  ".join(f"{row[k]!s:>9}" for k in keys))
    with open(args.out, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys)
        w.writeheader()
        w.writerows(rows)
    print(f"all over the makespan's lower bound; wrote {args.out}")


if __name__ == "__main__":
    main()
