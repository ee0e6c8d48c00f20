"""The paper's waypoint pruning and the whole-flight checks, old code against new, on the free-space crossing.

Inputs: the crossing of ``scale.py`` (N robots around (50, 100) crossing a free
300 x 200 m map) for each N, planned once with the continuous stage by the working tree
in a child process and saved to ``--inputs`` (reused when there): the discrete paths and
map, every robot's coefficients and durations, the knot times, the regions, the safety
distance and the limits.

Then, for each N, a child with the code of git revision ``--baseline`` (default ``main``,
extracted by ``baseline_code.py``) and a child with the working tree, one after the other
in the same session, each load the inputs and time, single-process, the best of
``--repeat`` calls of each part:

- ``prune``: ``prune_paths`` (the paper's pruning per horizon);
- ``certify``: ``certify`` of the whole flight;
- ``max_v``, ``max_a``, ``max_j``: ``max_derivative_norm_all`` of orders 1, 2, 3;
- ``min_sep``: ``exact_min_separation`` (reach two cells, as the continuous stage calls it);

and, in one more call each under ``tracemalloc``, the peak of memory allocated. The table
gives old and new seconds, the speed-up, and whether the results are the same: pruned
step indices equal, the certificate equal field for field, the minimum separation and
the maxima equal to 1e-12 relative. The fitted exponent of time in N (least squares of
log time on log N) is printed for both.

    python experiments/bench/final_checks.py [--sizes 100,300,1000] [--baseline main] [--repeat 3]
        [--inputs DIR] [--out experiments/bench/results/final_checks.csv]
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from baseline_code import ROOT, extract, run_child, use
from csv_table import write_csv
from scale import exponent, overrides

RESULTS = Path(__file__).parent / "results"
PARTS = ("prune", "certify", "max_v", "max_a", "max_j", "min_sep")


def make_inputs(n: int, path: Path) -> None:
    """Plan the crossing for ``n`` robots (working tree) and save what the parts take (runs in a child)."""
    use(str(ROOT))
    import mrfswarm
    from mrfswarm.pipeline import plan

    cfg = mrfswarm.load_config(None, overrides(n, True))
    r = plan(cfg, progress=False)
    c, reg = r.continuous, r.continuous.regions
    np.savez(path, paths=r.discrete.paths, free=r.scenario.grid.free, horizon=cfg.smoothing.horizon,
             resolution=r.scenario.grid.resolution,
             coefficients=np.stack([tr.coefficients for tr in c.trajectories]),
             durations=np.stack([tr.durations for tr in c.trajectories]), knot_times=c.knot_times,
             axes=reg.axes, lower=reg.lower, upper=reg.upper, oriented=reg.oriented, radius=reg.radius,
             distance=2 * cfg.scenario.robot_radius, limits=(cfg.smoothing.v_max, cfg.smoothing.a_max, cfg.smoothing.j_max))
    print(json.dumps({"N": n, "steps": int(r.discrete.n_steps)}))


def child(path: Path, code: str | None, repeat: int) -> None:
    """Time each part on the saved inputs with the code under ``code`` (the old or the working tree); print JSON."""
    use(code)
    from mrfswarm.continuous.certificate import certify
    from mrfswarm.continuous.receding_horizon import exact_min_separation
    from mrfswarm.continuous.regions import Regions
    from mrfswarm.discrete.pruning import prune_paths
    from mrfswarm.trajectory import PiecewisePolynomial
    from mrfswarm.trajectory.retiming import max_derivative_norm_all

    d = np.load(path)
    flight = [PiecewisePolynomial(T, a) for T, a in zip(d["durations"], d["coefficients"])]
    regions = Regions(d["axes"], d["lower"], d["upper"], d["oriented"], float(d["radius"]))
    limits = tuple(float(v) for v in d["limits"])
    calls = {
        "prune": lambda: prune_paths(d["paths"], d["free"], int(d["horizon"])),
        "certify": lambda: certify(flight, d["knot_times"], regions, float(d["distance"]), limits),
        "max_v": lambda: max_derivative_norm_all(flight, 1),
        "max_a": lambda: max_derivative_norm_all(flight, 2),
        "max_j": lambda: max_derivative_norm_all(flight, 3),
        "min_sep": lambda: exact_min_separation(flight, 2 * float(d["resolution"])),
    }
    out: dict = {"N": len(flight), "steps": len(d["knot_times"]) - 1}
    for part, call in calls.items():
        best = np.inf
        for _ in range(repeat):
            t0 = time.perf_counter()
            value = call()
            best = min(best, time.perf_counter() - t0)
        tracemalloc.start()
        call()
        out[f"{part}_peak_mb"] = tracemalloc.get_traced_memory()[1] / 2**20
        tracemalloc.stop()
        out[f"{part}_s"] = best
        if part == "prune":
            kept = [np.asarray(k, dtype=np.int64) for k in value]
            out["prune_kept"] = int(sum(len(k) for k in kept))
            out["prune_value"] = hashlib.sha256(b"".join(np.r_[len(k), k].tobytes() for k in kept)).hexdigest()
        elif part == "certify":
            out["certify_value"] = {"ok": value.ok, "problems": value.problems, "separation_bound": value.separation_bound,
                                    "region_violation": value.region_violation,
                                    "limit_bounds": list(value.limit_bounds), "near_pairs": value.near_pairs}
        else:
            out[f"{part}_value"] = float(value)
    print(json.dumps(out))


def same(part: str, old, new) -> bool:
    """Are the results of a part the same (to 1e-12 relative for the minimum and the maxima)?"""
    if part in ("prune", "certify"):
        return old == new
    return bool(abs(new - old) <= 1e-12 * abs(old))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", default="100,300,1000")
    ap.add_argument("--baseline", default="main", help="git revision of the old code")
    ap.add_argument("--repeat", type=int, default=3, help="calls per part and code; the best is kept")
    ap.add_argument("--inputs", type=Path, default=None, help="folder of the planned inputs (kept; default: temporary)")
    ap.add_argument("--out", type=Path, default=RESULTS / "final_checks.csv")
    ap.add_argument("--make-inputs", type=int, help=argparse.SUPPRESS)
    ap.add_argument("--child", type=Path, help=argparse.SUPPRESS)
    ap.add_argument("--code", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.make_inputs is not None:
        make_inputs(args.make_inputs, args.child)
        return
    if args.child is not None:
        child(args.child, args.code, args.repeat)
        return
    sizes = [int(v) for v in args.sizes.split(",")]
    rows, results = [], {}
    with tempfile.TemporaryDirectory() as tmp:
        inputs = args.inputs or Path(tmp)
        inputs.mkdir(parents=True, exist_ok=True)
        base = extract(args.baseline, Path(tmp))
        print(f"{'N':>5} {'part':>8} {'old s':>8} {'new s':>8} {'speed-up':>9} {'old MB':>8} {'new MB':>8}  same",
              flush=True)
        for n in sizes:
            path = inputs / f"crossing_{n}.npz"
            if not path.exists():
                run_child(Path(__file__), ["--make-inputs", str(n), "--child", str(path)], None)
            run = {kind: run_child(Path(__file__), ["--child", str(path), "--repeat", str(args.repeat)], code)
                   for kind, code in (("old", base), ("new", ROOT))}
            results[n] = run
            for part in PARTS:
                old, new = run["old"], run["new"]
                row = {"N": n, "steps": new["steps"], "part": part, "old_s": old[f"{part}_s"], "new_s": new[f"{part}_s"],
                       "speedup": old[f"{part}_s"] / new[f"{part}_s"], "old_peak_mb": old[f"{part}_peak_mb"],
                       "new_peak_mb": new[f"{part}_peak_mb"], "same": same(part, old[f"{part}_value"], new[f"{part}_value"])}
                rows.append(row)
                print(f"{n:>5} {part:>8} {row['old_s']:>8.3f} {row['new_s']:>8.3f} {row['speedup']:>8.1f}x "
                      f"{row['old_peak_mb']:>8.1f} {row['new_peak_mb']:>8.1f}  {row['same']}", flush=True)
    slopes = []
    if len(sizes) < 2:
        print("exponent of time in N: needs two sizes or more (--sizes)")
    for part in PARTS:
        s = {k: exponent(sizes, [results[n][k][f"{part}_s"] for n in sizes]) for k in ("old", "new")}
        slopes.append({"part": part, "old_exponent": s["old"], "new_exponent": s["new"], "sizes": args.sizes})
        if len(sizes) >= 2:
            print(f"exponent of time in N, {part:>8}: old {s['old']:.2f}, new {s['new']:.2f}")
    write_csv(args.out, rows, float_format=".4g")
    exps = args.out.with_name(args.out.stem + "_exponents.csv")
    write_csv(exps, slopes, float_format=".3g")
    print(f"wrote {args.out} and {exps}")


if __name__ == "__main__":
    main()
