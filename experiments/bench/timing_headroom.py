"""How much of the default flight's time goes to the shared time grid: what per-robot timing could gain.

All robots fly one common time grid (:mod:`mrfswarm.continuous.regions`: the relative safe
corridors hold between pieces of the same interval), so every step lasts what its slowest
mover needs: a robot starting, stopping or turning slows the whole swarm for that step. Per
case of ``flight_quality.py`` (its maps and settings, the working tree's code), from the
discrete plan and the bold speed profile of the default time grid (``"nominal"`` in ``PROFILES`` of
:mod:`mrfswarm.continuous.receding_horizon`; the fast profile before it is tried on a window's flown steps only),
all over the makespan's lower bound:

- ``flown``: the default flight, planned here (the continuous stage, simulation off);
- ``shared``: the bold profile on the common grid (each step its slowest mover's need),
  what the default flies where every window accepts its bold attempt;
- ``own``: the slowest robot flying its own moves on the same profile with no shared grid
  (each robot its own need per step), a bound on what per-robot timing could reach with these
  discrete paths and this profile;
- ``ordered``: per-robot timing that keeps the discrete plan's order where it matters
  (:func:`ordered_makespan`, regions at growth 0): a robot's step may not start before every
  step of another robot that comes within 2 r of it in an earlier step has ended, and robots
  within 2 r of each other in the same step share that step's interval (their relative
  corridor needs one). Waits take no time and a delayed robot loses no speed, so it is
  optimistic too, but unlike ``own`` it makes a robot wait for the robots it waited for;
- ``ordered_grown``: the same with the regions at the configured growth (1 cell by default);
- ``path``: the longest discrete path at v_max (the discrete plan's own share).

    python experiments/bench/timing_headroom.py [--cases corridor,...] [--out F.csv]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
import numpy as np
from csv_table import text_table, write_csv
from flight_quality import DEFAULT_CASES, RESULTS, case_config
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components


def ordered_makespan(need: np.ndarray, lo: np.ndarray, hi: np.ndarray, distance: float) -> float:
    """The earliest finish of steps ``need`` (T, N) seconds on per-robot time lines, with regions' bounding boxes
    ``lo``, ``hi`` (T, N, d): step k of robot i and step k' of robot j whose boxes come within ``distance`` are
    ordered as in the discrete plan (k' < k: j's ends before i's starts) or, when k' = k, share one interval."""
    from mrfswarm.continuous.regions import near_pairs

    T, N = need.shape
    pairs = near_pairs(lo.reshape(T * N, -1), hi.reshape(T * N, -1), distance)  # over all (step, robot) boxes
    pairs = pairs[pairs[:, 0] % N != pairs[:, 1] % N]  # a robot's own steps are ordered by its time line
    k1, k2 = pairs[:, 0] // N, pairs[:, 1] // N
    same = k1 == k2
    graph = coo_matrix((np.ones(same.sum()), (pairs[same, 0], pairs[same, 1])), shape=(T * N, T * N))
    _, cls = connected_components(graph, directed=False)  # the classes sharing a step's interval
    dur = np.zeros(cls.max() + 1)
    np.maximum.at(dur, cls, need.reshape(-1))
    early, late = np.where(k1 < k2, pairs[:, 0], pairs[:, 1])[~same], np.where(k1 < k2, pairs[:, 1], pairs[:, 0])[~same]
    order = np.argsort(late // N, kind="stable")
    early, late = early[order], late[order]
    bounds = np.searchsorted(late // N, np.arange(T + 1))
    end = np.zeros(T * N)
    prev = np.zeros(N)
    for k in range(T):
        start = prev.copy()
        e, lt = early[bounds[k]:bounds[k + 1]], late[bounds[k]:bounds[k + 1]]
        np.maximum.at(start, lt - k * N, end[e])
        members = cls[k * N:(k + 1) * N]
        first = np.zeros(dur.shape)
        np.maximum.at(first, members, start)
        end[k * N:(k + 1) * N] = prev = first[members] + dur[members]
    return float(end.max()) if end.size else 0.0


def measure(case: str) -> dict:

    from mrfswarm.config import apply_overrides, from_dict
    from mrfswarm.continuous.receding_horizon import PROFILES, drift_room, motion_acceleration
    from mrfswarm.continuous.regions import build_regions
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
    _, cruise, acc = next(p for p in PROFILES if p[0] == "nominal")
    a = motion_acceleration(sm.v_max, sm.a_max, sm.j_max, acc)
    drift = drift_room(res, cfg.scenario.robot_radius)
    need, length = robot_needs(paths, res, cruise * sm.v_max, a, drift)
    shared = motion_profile(paths, res, cruise * sm.v_max, a, drift).durations.sum()
    flown = float(r.smoothed().knot_times[-1])
    radius = cfg.scenario.robot_radius
    ordered = [ordered_makespan(need, *build_regions(paths, scn.grid, radius, g).bounding_boxes(), 2 * radius)
               for g in (0.0, sm.region_growth)]
    return {"case": case, "robots": paths.shape[1], "steps": len(paths) - 1, "bound_s": round(bound, 2),
            "flown": round(flown / bound, 2), "shared": round(shared / bound, 2),
            "own": round(float(need.sum(axis=0).max()) / bound, 2),
            "ordered": round(ordered[0] / bound, 2), "ordered_grown": round(ordered[1] / bound, 2),
            "path": round(float(length.sum(axis=0).max()) / sm.v_max / bound, 2)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cases", default=DEFAULT_CASES)
    ap.add_argument("--out", type=Path, default=RESULTS / "timing_headroom.csv")
    args = ap.parse_args()
    rows = [measure(case) for case in args.cases.split(",")]
    print(text_table(rows, sep="  "))
    write_csv(args.out, rows)
    print(f"all over the makespan's lower bound; wrote {args.out}")


if __name__ == "__main__":
    main()
