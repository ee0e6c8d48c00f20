"""Benchmark the time optimization of ``mrfswarm smooth``: duration refinement and retiming.

uav_trajectories users report its time optimization taking minutes beyond 15 waypoints;
the target here is 100 waypoints refined in at most 1 s. For 10, 30, 100 and 300
waypoints (a seeded 2-D random walk, steps of 0.5-1.5 m, as ``min_snap.py``), starting
from constant speed (1 m/s), one run compares:

- ``unrefined``: the closed-form min-snap solve at those durations (the baseline's cost;
  its time is that of one solve);
- ``refine: adjoint gradient``: :func:`mrfswarm.trajectory.refine_durations` as
  ``mrfswarm smooth --refine-time`` calls it (no weight: the total is kept and
  redistributed; L-BFGS-B on :math:`J^* + k_T \\sum T` with the exact gradient of the
  banded closed form), median of repeats;
- ``refine: finite differences``: the same optimizer, weight and end scaling, with the
  gradient by forward differences of :math:`J^*` (one more banded solve per piece per
  gradient: the naive way), once, in a child process with a time limit (``--timeout``).

For each: wall time, iterations, the snap integral :math:`J^*` at the kept total (both
refinements must agree), and the resulting flight within the limits (default v 2 m/s,
a 4 m/s^2): the duration after uniform scaling until a limit is tight, and after toppra
retiming (``retime_toppra``; its wall time too). A second table runs the command a user
runs, ``mrfswarm smooth W.csv --out T.csv`` with no option, with ``--refine-time --v-max
--a-max`` and with ``--retime toppra --refine-time --v-max --a-max``, in a subprocess
(wall time including Python's start-up and imports, median of ``--cli-reps``).

Writes every row to ``experiments/bench/results/smooth_time.csv`` (``--out`` to change).
The machine's load and ``OPENBLAS_NUM_THREADS`` are printed: on a loaded 2-core machine
OpenBLAS's threads make L-BFGS-B's own small linear algebra several times slower.

    PYTHONPATH=. python experiments/bench/smooth_time.py               # ~2 minutes
    PYTHONPATH=. python experiments/bench/smooth_time.py --sizes 10 100 --cli-reps 1
"""

from __future__ import annotations

import argparse
import os
import pathlib
import statistics
import subprocess
import sys
import tempfile
import time
from functools import partial

import numpy as np
from csv_table import write_csv
from min_snap import in_child, repeat, waypoints
from scipy.optimize import minimize

from mrfswarm.trajectory import (
    MinSnapProblem,
    constant_speed_durations,
    refine_durations,
    retime_toppra,
    scale_to_limits,
    solve_banded,
    solve_min_snap,
)
from mrfswarm.trajectory.time_allocation import stationary_time_weight

RESULTS = pathlib.Path(__file__).parent / "results" / "smooth_time.csv"
ROOT = pathlib.Path(__file__).resolve().parents[2]


def refine_finite_differences(W: np.ndarray, T0: np.ndarray, max_iter: int = 200, tol: float = 1e-9):
    """The baseline: ``refine_durations(W, T0)``'s optimization with a forward-difference gradient.

    Same weight (the stationary one of ``T0``), variables (log T), bounds, optimizer and
    tolerances, and the same scaling back to the initial total; only the gradient differs.
    Returns the durations and the iteration count.
    """
    base = MinSnapProblem(W, T0)
    k = stationary_time_weight(W, T0)
    tmin = 1e-3 * T0.min()

    def cost(T):
        return solve_banded(base.with_data(durations=T)).cost

    F0 = cost(T0) + k * T0.sum()

    def fun(u):
        T = np.exp(u)
        J = cost(T)
        g = np.empty_like(T)
        for i in range(T.size):
            Th = T.copy()
            Th[i] += 1e-7 * T[i]
            g[i] = (cost(Th) - J) / (1e-7 * T[i])
        return (J + k * T.sum()) / F0, (g + k) * T / F0

    res = minimize(fun, np.log(T0), jac=True, method="L-BFGS-B", bounds=[(np.log(tmin), None)] * T0.size,
                   options=dict(maxiter=max_iter, ftol=tol, gtol=1e-10))
    T = np.exp(res.x)
    return T * (T0.sum() / T.sum()), int(res.nit)


def flight(W: np.ndarray, T: np.ndarray, v_max: float, a_max: float) -> dict:
    """Snap integral at ``T``, and the durations within the limits: uniform scaling, toppra."""
    traj = solve_min_snap(W, T).trajectory
    t0 = time.perf_counter()
    rt = retime_toppra(traj, v_max, a_max)
    return dict(cost=solve_banded(MinSnapProblem(W, T)).cost, total_s=float(T.sum()),
                scaled_s=scale_to_limits(traj, v_max, a_max, allow_speedup=True).trajectory.duration,
                toppra_s=rt.trajectory.duration, toppra_method=rt.method, toppra_ms=1e3 * (time.perf_counter() - t0))


def cli_times(W: np.ndarray, v_max: float, a_max: float, reps: int) -> dict:
    """Median wall time of ``mrfswarm smooth`` in a subprocess, per variant (seconds)."""
    variants = {"plain": [], "refine+limits": ["--refine-time", "--v-max", str(v_max), "--a-max", str(a_max)],
                "refine+toppra": ["--refine-time", "--retime", "toppra", "--v-max", str(v_max), "--a-max", str(a_max)]}
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    out = {}
    with tempfile.TemporaryDirectory() as d:
        wp = pathlib.Path(d) / "w.csv"
        wp.write_text("x,y\n" + "".join(f"{x!r},{y!r}\n" for x, y in W.tolist()))
        for name, extra in variants.items():
            times = []
            for _ in range(reps):
                t0 = time.perf_counter()
                r = subprocess.run([sys.executable, "-m", "mrfswarm.cli", "smooth", str(wp), "--out",
                                    str(pathlib.Path(d) / "t.csv"), "--overwrite", *extra], capture_output=True, text=True,
                                   env=env)
                times.append(time.perf_counter() - t0)
                if r.returncode != 0:
                    raise RuntimeError(f"mrfswarm smooth {' '.join(extra)} failed: {r.stderr.strip()}")
            out[name] = statistics.median(times)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[10, 30, 100, 300], help="numbers of waypoints")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--v-max", type=float, default=2.0)
    ap.add_argument("--a-max", type=float, default=4.0)
    ap.add_argument("--budget", type=float, default=2.0, help="seconds of repeats per timed refinement")
    ap.add_argument("--timeout", type=float, default=120.0, help="seconds for the finite-difference refinement")
    ap.add_argument("--cli-reps", type=int, default=3, help="subprocess runs per command variant")
    ap.add_argument("--out", type=pathlib.Path, default=RESULTS, help="CSV to write")
    args = ap.parse_args()
    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores; "
          f"OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS', 'unset')}; "
          f"limits v {args.v_max} m/s, a {args.a_max} m/s^2\n")
    Wu = waypoints(4, 99)  # warm-up: imports and first calls
    refine_durations(Wu, constant_speed_durations(Wu, 1.0))
    retime_toppra(solve_min_snap(Wu, constant_speed_durations(Wu, 1.0)).trajectory, args.v_max, args.a_max)
    rows = []
    for n in args.sizes:
        W = waypoints(n - 1, args.seed + n)
        T0 = constant_speed_durations(W, 1.0)
        solve_s = statistics.median(t for t, _ in repeat(partial(_timed, solve_min_snap, W, T0), args.budget / 4))
        runs = repeat(partial(_timed, refine_durations, W, T0), args.budget)
        adj_s = statistics.median(t for t, _ in runs)
        ref = runs[-1][1]
        fd, note = in_child(partial(_timed, refine_finite_differences, W, T0), args.timeout)
        base = dict(waypoints=n, pieces=n - 1)
        rows.append(dict(base, method="unrefined", time_s=solve_s, iterations=0,
                         **flight(W, T0, args.v_max, args.a_max)))
        rows.append(dict(base, method="refine: adjoint gradient", time_s=adj_s, iterations=ref.iterations,
                         time_weight=ref.time_weight, **flight(W, ref.durations, args.v_max, args.a_max)))
        if fd is None:
            rows.append(dict(base, method="refine: finite differences", note=note))
        else:
            fd_s, (T_fd, it_fd) = fd
            rows.append(dict(base, method="refine: finite differences", time_s=fd_s, iterations=it_fd,
                             **flight(W, T_fd, args.v_max, args.a_max)))
            rows[-2]["x_vs_fd"] = fd_s / adj_s
        print_table([r for r in rows if r["waypoints"] == n])
    print("mrfswarm smooth in a subprocess (wall time incl. Python start-up and imports, median):")
    print(f"{'waypoints':>9} {'plain':>9} {'--refine-time + limits':>23} {'--refine-time --retime toppra':>30}")
    for n in args.sizes:
        c = cli_times(waypoints(n - 1, args.seed + n), args.v_max, args.a_max, args.cli_reps)
        print(f"{n:>9} {c['plain']:>8.2f}s {c['refine+limits']:>22.2f}s {c['refine+toppra']:>29.2f}s")
        for name, method in (("plain", "cli: mrfswarm smooth"), ("refine+limits", "cli: --refine-time --v-max --a-max"),
                             ("refine+toppra", "cli: --refine-time --retime toppra --v-max --a-max")):
            rows.append(dict(waypoints=n, pieces=n - 1, method=method, time_s=c[name]))
    cols = ["waypoints", "pieces", "method", "time_s", "iterations", "x_vs_fd", "cost", "total_s", "scaled_s",
            "toppra_s", "toppra_method", "toppra_ms", "time_weight", "note"]
    write_csv(args.out, rows, cols, float_format=".6g")
    print(f"\nwrote {args.out}")


def _timed(fn, *a):
    t0 = time.perf_counter()
    out = fn(*a)
    return time.perf_counter() - t0, out


def fmt(v, spec):
    return "" if v in ("", None) else format(v, spec)


def print_table(rows):
    print(f"{'waypoints':>9} {'method':<27} {'time':>9} {'iters':>5} {'x vs FD':>7} | {'snap J*':>10} {'total':>8} | "
          f"{'scaled to limits':>16} {'toppra':>8} {'toppra time':>11}")
    for r in rows:
        note = f"  {r['note']}" if r.get("note") else ""
        print(f"{r['waypoints']:>9} {r['method']:<27} {fmt(r.get('time_s'), '.4f'):>8}s "
              f"{fmt(r.get('iterations'), 'd'):>5} {fmt(r.get('x_vs_fd'), '.3g'):>7} | "
              f"{fmt(r.get('cost'), '.5g'):>10} {fmt(r.get('total_s'), '.1f'):>7}s | "
              f"{fmt(r.get('scaled_s'), '.1f'):>15}s {fmt(r.get('toppra_s'), '.1f'):>7}s "
              f"{fmt(r.get('toppra_ms'), '.0f'):>9}ms{note}")
    print("(time: the solve or the refinement; snap J* at the same total duration; scaled to limits: uniformly "
          "until v or a is tight)\n")


if __name__ == "__main__":
    main()
