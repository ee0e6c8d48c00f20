"""Benchmark min-snap smoothing: the banded closed form, every installed QP backend, RotorPy.

For 5, 10, 100 and 1000 pieces in 2-D (a seeded random walk, steps of 0.5-1.5 m,
durations at 1 m/s) it times, median of repeats:

- ``closed_form``: :func:`mrfswarm.trajectory.solve_min_snap` on the banded fast path
  (validation, assembly, LAPACK banded LU, trajectory construction: everything);
- every installed backend of ``solvers.qp.BACKENDS`` on the formulated QP
  (``MinSnapSolver(name, formulated=True)``; the registry's ``closed_form``, if
  registered, is its generic equality-only KKT solver): the one-time CasADi compilation
  of the shape apart, then *cold* (formulate = evaluate the compiled functions and build
  the sparse QP, setup, solve) and *warm* (same shape, new waypoints: formulate, the
  backend's update, warm-started solve);
- RotorPy's ``MinSnap`` (cvxopt, dense) on the same waypoints in 3-D at constant z,
  with its own time allocation at the same average speed (identical durations here),
  ``verbose=False``; in a child process with a time limit (default 60 s per size),
  reported as a timeout beyond it (every backend's measurement also runs in a child
  with a time limit, ``--timeout``, default 120 s). It solves four QPs (x, y, z, yaw), adds snap
  continuity and a speed bound at each piece's midpoint: a slightly larger problem,
  but the same job (what a user of RotorPy runs to smooth waypoints).

``x RotorPy`` is RotorPy's median time over the method's (cold total) at that size.
``max err`` is the largest position difference to the closed form (sampled at 50 Hz).
Writes every row to ``experiments/bench/results/min_snap.csv`` (``--out`` to change).

    PYTHONPATH=. python experiments/bench/min_snap.py              # ~2-4 minutes
    PYTHONPATH=. python experiments/bench/min_snap.py --sizes 5 10 --rotorpy-timeout 20
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import pathlib
import statistics
import time
from functools import partial

import numpy as np
from csv_table import write_csv

import solvers.qp
from mrfswarm.trajectory import MinSnapProblem, MinSnapSolver, constant_speed_durations, solve_min_snap
from mrfswarm.trajectory.formulation import compiled_min_snap

RESULTS = pathlib.Path(__file__).parent / "results" / "min_snap.csv"


def waypoints(pieces: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    ang = rng.uniform(0, 2 * np.pi, pieces)
    step = rng.uniform(0.5, 1.5, pieces)
    return np.vstack([[0.0, 0.0], np.cumsum(np.c_[step * np.cos(ang), step * np.sin(ang)], axis=0)])


def repeat(fn, budget_s: float, max_reps: int = 200, min_reps: int = 3) -> list:
    """Call ``fn`` until ``budget_s`` is spent (at least ``min_reps`` times); return its results."""
    out, t0 = [], time.perf_counter()
    while len(out) < min_reps or (len(out) < max_reps and time.perf_counter() - t0 < budget_s):
        out.append(fn())
    return out


def ms(x: float) -> float:
    return 1e3 * x


def bench_closed_form(W, T, budget):
    def run():
        t0 = time.perf_counter()
        res = solve_min_snap(W, T)
        return time.perf_counter() - t0, res

    runs = repeat(run, budget, max_reps=2000)
    return statistics.median(r[0] for r in runs), runs[-1][1]


def bench_backend(name, W, T, budget, rng, ref):
    """Cold and warm medians of one backend (run in a child: see :func:`in_child`)."""
    problem = MinSnapProblem(W, T)

    def cold():
        t0 = time.perf_counter()
        r = MinSnapSolver(name, formulated=True, warm=False).solve(problem)
        return time.perf_counter() - t0, r

    cold_runs = repeat(cold, budget)
    solver = MinSnapSolver(name, formulated=True, warm=True)
    solver.solve(problem)

    def warm():
        Wn = W + rng.normal(scale=0.05, size=W.shape)
        t0 = time.perf_counter()
        r = solver.solve(MinSnapProblem(Wn, T))
        return time.perf_counter() - t0, r

    warm_runs = repeat(warm, budget)

    def parts(runs):
        return dict(
            formulate=statistics.median(r[1].formulate_time_s for r in runs),
            setup=statistics.median(r[1].setup_time_s for r in runs),
            solve=statistics.median(r[1].solve_time_s for r in runs),
            total=statistics.median(r[0] for r in runs),
            iters=statistics.median(r[1].solution.iterations for r in runs),
        )

    return parts(cold_runs), parts(warm_runs), max_err(cold_runs[-1][1].trajectory, ref)


def in_child(fn, timeout_s: float):
    """Run ``fn()`` in a forked child; return ``(result, "")`` or ``(None, reason)`` on timeout/error.

    A solver that does not scale (a dense method on 8000 variables) or RotorPy's dense
    cvxopt QPs would otherwise hold the benchmark for minutes.
    """
    ctx = mp.get_context("fork")
    parent, child = ctx.Pipe(duplex=False)

    def target():
        try:
            child.send(("ok", fn()))
        except BaseException as e:  # report, do not hang the parent
            msg = str(e).splitlines()[0] if str(e) else ""
            child.send(("error", f"failed: {type(e).__name__}: {msg}"))

    p = ctx.Process(target=target, daemon=True)
    p.start()
    if not parent.poll(timeout_s):
        p.terminate()
        p.join(5)
        return None, f"timeout > {timeout_s:.0f} s"
    status, payload = parent.recv()
    p.join(5)
    return (payload, "") if status == "ok" else (None, payload)


def bench_rotorpy(W, timeout_s, reps):
    W3 = np.c_[W, np.ones(len(W))]

    def run():
        from rotorpy.trajectories.minsnap import MinSnap

        times = []
        for _ in range(reps):
            t0 = time.perf_counter()
            MinSnap(W3, v_avg=1.0, verbose=False)
            times.append(time.perf_counter() - t0)
        return statistics.median(times)

    return in_child(run, timeout_s)


def max_err(traj, ref):
    t = np.arange(0.0, ref.duration, 0.02)
    return float(np.abs(traj(t) - ref(t)).max())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[5, 10, 100, 1000])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--budget", type=float, default=1.0, help="seconds of repeats per measurement")
    ap.add_argument("--rotorpy-timeout", type=float, default=60.0)
    ap.add_argument("--timeout", type=float, default=120.0, help="seconds per backend and size (child process)")
    ap.add_argument("--out", type=pathlib.Path, default=RESULTS, help="CSV to write")
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed + 1)
    names = solvers.qp.available()
    # warm-up: imports, first-call costs of numpy/scipy/LAPACK and of every backend
    Wu = waypoints(3, 99)
    for _ in range(3):
        solve_min_snap(Wu, constant_speed_durations(Wu, 1.0))
        for name in names:
            MinSnapSolver(name, formulated=True).solve(MinSnapProblem(Wu, constant_speed_durations(Wu, 1.0)))
    rows = []
    for M in args.sizes:
        W = waypoints(M, args.seed + M)
        T = constant_speed_durations(W, 1.0)
        cf, ref = bench_closed_form(W, T, args.budget)
        ours = []
        ours.append(dict(pieces=M, method="closed_form (banded)", compile_ms="", cold_formulate_ms=0.0, cold_setup_ms=0.0,
                         cold_solve_ms=ms(cf), cold_total_ms=ms(cf), warm_formulate_ms="", warm_setup_ms="",
                         warm_solve_ms="", warm_total_ms="", iterations=0, max_err=0.0, total_s=cf, note=""))
        t0 = time.perf_counter()
        compiled_min_snap(MinSnapProblem(W, T).shape)  # once, in the parent: the children inherit it
        compile_ms = ms(time.perf_counter() - t0)
        for name in names:
            out, note = in_child(partial(bench_backend, name, W, T, args.budget, rng, ref.trajectory), args.timeout)
            if out is None:
                ours.append(dict(pieces=M, method=name, compile_ms=compile_ms, note=note))
                continue
            cold, warm, err = out
            ours.append(dict(pieces=M, method=name, compile_ms=compile_ms,
                             cold_formulate_ms=ms(cold["formulate"]), cold_setup_ms=ms(cold["setup"]),
                             cold_solve_ms=ms(cold["solve"]), cold_total_ms=ms(cold["total"]),
                             warm_formulate_ms=ms(warm["formulate"]), warm_setup_ms=ms(warm["setup"]),
                             warm_solve_ms=ms(warm["solve"]), warm_total_ms=ms(warm["total"]),
                             iterations=cold["iters"], max_err=err, total_s=cold["total"], note=""))
        # RotorPy last, in a child process, so that its imports and memory do not disturb our timings
        rp, rp_note = bench_rotorpy(W, args.rotorpy_timeout, 15 if M <= 10 else (3 if M <= 100 else 1))
        for r in ours:
            r["x_rotorpy"] = rp / r["total_s"] if (rp and r.get("total_s")) else ""
        rows += ours
        rows.append(dict(pieces=M, method="rotorpy MinSnap (cvxopt)", cold_total_ms=ms(rp) if rp else "",
                         x_rotorpy=1.0 if rp else "", note=rp_note))
        print_table([r for r in rows if r["pieces"] == M])
    cols = ["pieces", "method", "compile_ms", "cold_formulate_ms", "cold_setup_ms", "cold_solve_ms", "cold_total_ms",
            "warm_formulate_ms", "warm_setup_ms", "warm_solve_ms", "warm_total_ms", "iterations", "max_err",
            "x_rotorpy", "note"]
    write_csv(args.out, rows, cols, float_format=".6g")
    print(f"\nwrote {args.out}")


def fmt(v, spec=".3f"):
    return "" if v in ("", None) else format(v, spec)


def print_table(rows):
    head = (f"{'pieces':>6} {'method':<26} {'compile':>8} | {'cold: form':>10} {'setup':>8} {'solve':>8} {'total':>8} | "
            f"{'warm: form':>10} {'setup':>8} {'solve':>8} {'total':>8} | {'iters':>5} {'max err':>8} {'x RotorPy':>9}")
    print(head)
    for r in rows:
        note = f"  {r['note']}" if r.get("note") else ""
        print(f"{r['pieces']:>6} {r['method']:<26} {fmt(r.get('compile_ms'), '.1f'):>8} | "
              f"{fmt(r.get('cold_formulate_ms')):>10} {fmt(r.get('cold_setup_ms')):>8} {fmt(r.get('cold_solve_ms')):>8} "
              f"{fmt(r.get('cold_total_ms')):>8} | {fmt(r.get('warm_formulate_ms')):>10} {fmt(r.get('warm_setup_ms')):>8} "
              f"{fmt(r.get('warm_solve_ms')):>8} {fmt(r.get('warm_total_ms')):>8} | {fmt(r.get('iterations'), '.0f'):>5} "
              f"{fmt(r.get('max_err'), '.1e'):>8} {fmt(r.get('x_rotorpy'), '.3g'):>9}{note}")
    print("(times in ms; compile = one-time CasADi compilation of the shape)\n")


if __name__ == "__main__":
    main()
