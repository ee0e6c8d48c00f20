"""What a map allows its slowest robot: the bound robot alone, flown as fast as its limits allow.

Issue 18 asks the refined flight to reach 1.25 x the makespan's lower bound "where the map allows".
The bound (:func:`mrfswarm.flight_quality.makespan_lower_bound`) is the longest shortest free path
from a robot's start cell to its final cell, flown at ``v_max``: it has no start from rest, no stop,
no acceleration or jerk limit. This script measures how far above it even one robot alone must
fly, on each bench map (``flight_quality.py``'s cases):

- the swarm's discrete plan (the default config) names the **bound robot** and its cells;
- its shortest free path (the bound's graph: 8-connected without corner cutting; on voxels
  26-connected), each move's box grown over free cells (``build_regions``, up to the map's size)
  and shrunk by the robot radius: a corridor of convex boxes;
- the fastest flight through it from rest to rest (**solo**): a triple integrator with constant jerk
  per interval, one phase per move with its own duration and ``--knots`` intervals, each knot
  in its phase's box (the knot between two phases in both), speed, acceleration and jerk within
  ``v_max``, ``a_max``, ``j_max`` as norms (as the planner's limits), minimizing the sum of the
  durations; Ipopt through CasADi.

It is a reference, not a bound: Ipopt finds a local optimum through one chain of boxes, and only
knots are held in their boxes. It tells what a time-optimal planner could fly that robot in with no
other robot around; the swarm's refined flight over it is the planner's own share of the gap.

With ``--flight`` the swarm's makespans (default and refined, flight simulation off) are planned
too. Prints the table and writes it as CSV to ``--out`` (default ``results/solo_reference.csv``, the
committed one).

    python experiments/bench/solo_reference.py --cases arena8,doorway --flight
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from csv_table import text_table, write_csv  # noqa: E402
from flight_quality import case_config  # noqa: E402

RESULTS = Path(__file__).parent / "results"


def shortest_path(free: np.ndarray, start: np.ndarray, end: np.ndarray, resolution: float) -> np.ndarray:
    """(L + 1, d) cells of a shortest free path from ``start`` to ``end`` on the bound's graph."""
    from scipy.sparse.csgraph import dijkstra

    from mrfswarm.flight_quality import _flat, _graph

    graph = _graph(free, resolution)
    s, e = int(_flat(start, free.shape)), int(_flat(end, free.shape))
    dist, pred = dijkstra(graph, directed=True, indices=s, return_predecessors=True)
    if not np.isfinite(dist[e]):
        raise SystemExit(f"no free path from {start} to {end}")
    chain = [e]
    while chain[-1] != s:
        chain.append(int(pred[chain[-1]]))
    return np.array(np.unravel_index(np.array(chain[::-1]), free.shape)).T


def fastest_flight(p0: np.ndarray, p1: np.ndarray, regions, v_max: float, a_max: float, j_max: float,
                   knots: int) -> tuple[float, np.ndarray]:
    """The least total duration from rest at ``p0`` to rest at ``p1`` through ``regions`` (one robot's, one
    phase per step) within the limits as norms; and the phases' durations."""
    import casadi as ca

    d = p0.size
    K = regions.steps
    opti = ca.Opti()
    T = opti.variable(K)
    X = opti.variable(3 * d, K * knots + 1)  # position, velocity, acceleration
    U = opti.variable(d, K * knots)  # jerk
    for k in range(K):
        h = T[k] / knots
        axes, lo, hi = regions.axes[k, 0], regions.lower[k, 0], regions.upper[k, 0]
        for i in range(knots):
            n = k * knots + i
            p, v, a, u = X[0:d, n], X[d:2 * d, n], X[2 * d:, n], U[:, n]
            opti.subject_to(X[:, n + 1] == ca.vertcat(p + v * h + a * h**2 / 2 + u * h**3 / 6,
                                                       v + a * h + u * h**2 / 2, a + u * h))
            opti.subject_to(ca.sumsqr(u) <= j_max**2)
        for n in range(k * knots, (k + 1) * knots + 1):  # the phase's knots, both ends included
            s = ca.mtimes(ca.DM(axes), X[0:d, n])
            opti.subject_to(opti.bounded(ca.DM(lo), s, ca.DM(hi)))
    for n in range(K * knots + 1):
        opti.subject_to(ca.sumsqr(X[d:2 * d, n]) <= v_max**2)
        opti.subject_to(ca.sumsqr(X[2 * d:, n]) <= a_max**2)
    rest = np.zeros(2 * d)
    opti.subject_to(X[:, 0] == np.concatenate([p0, rest]))
    opti.subject_to(X[:, -1] == np.concatenate([p1, rest]))
    opti.subject_to(T >= 1e-3)
    opti.minimize(ca.sum1(T))
    # start: the box centres' chain at a modest speed
    centres = np.einsum("kab,ka->kb", regions.axes[:, 0], (regions.lower[:, 0] + regions.upper[:, 0]) / 2)
    pts = np.vstack([p0, (centres[:-1] + centres[1:]) / 2 if K > 1 else np.empty((0, d)), p1])
    length = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    opti.set_initial(T, np.maximum(length, 0.1) / (0.7 * v_max) + 0.3 / K)
    s = np.linspace(0, len(pts) - 1, K * knots + 1)
    opti.set_initial(X[0:d, :], np.array([np.interp(s, np.arange(len(pts)), pts[:, c]) for c in range(d)]))
    opti.solver("ipopt", {"print_time": False}, {"print_level": 0, "sb": "yes", "max_iter": 3000, "tol": 1e-8})
    sol = opti.solve()
    durations = np.atleast_1d(np.asarray(sol.value(T), dtype=float))
    return float(durations.sum()), durations


def row(case: str, knots: int, flight: bool) -> dict:
    import dataclasses

    from mrfswarm.config import apply_overrides, from_dict
    from mrfswarm.continuous.regions import build_regions
    from mrfswarm.flight_quality import free_path_lengths
    from mrfswarm.pipeline import plan

    data, base = case_config(case)
    cfg = from_dict(apply_overrides(data, ["simulation.enabled=false", "smoothing.enabled=false"]), base)
    r = plan(cfg, progress=False)
    grid, P = r.scenario.grid, r.discrete.paths
    lengths = free_path_lengths(grid.free, P[0], P[-1], grid.resolution)
    i = int(np.nanargmax(lengths))
    sm = cfg.smoothing
    bound = float(lengths[i]) / sm.v_max
    path = shortest_path(grid.free, P[0][i], P[-1][i], grid.resolution)
    regions = build_regions(path[:, None, :], grid, cfg.scenario.robot_radius, growth=float(max(grid.shape)))
    t0 = time.perf_counter()
    solo, _ = fastest_flight(grid.cell_to_world(path[0]), grid.cell_to_world(path[-1]), regions, sm.v_max,
                             sm.a_max, sm.j_max, knots)
    out = {"case": case, "robot": i, "moves": len(path) - 1, "bound_s": round(bound, 3), "solo_s": round(solo, 3),
           "solo": round(solo / bound, 3), "solo_solve_s": round(time.perf_counter() - t0, 1)}
    if flight:
        for variant, extra in (("default", []), ("refined", ["smoothing.time_refinement=true"])):
            c = from_dict(apply_overrides(case_config(case)[0], ["simulation.enabled=false", *extra]), base)
            m = plan(dataclasses.replace(c), progress=False).continuous.makespan_s
            out[f"{variant}_s"] = round(m, 3)
            out[variant] = round(m / bound, 3)
            out[f"{variant}_over_solo"] = round(m / solo, 3)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cases", default="arena8,doorway,corridor")
    ap.add_argument("--knots", type=int, default=8, help="intervals per move (default 8)")
    ap.add_argument("--flight", action="store_true", help="also plan the swarm's flights, default and refined")
    ap.add_argument("--out", type=Path, default=RESULTS / "solo_reference.csv")
    args = ap.parse_args()
    rows = []
    for case in args.cases.split(","):
        rows.append(row(case, args.knots, args.flight))
        print(" ".join(f"{k}={v}" for k, v in rows[-1].items()), file=sys.stderr, flush=True)
    write_csv(args.out, rows)
    print(text_table(rows, width=10))
    print(f"-> {args.out}")


if __name__ == "__main__":
    main()
