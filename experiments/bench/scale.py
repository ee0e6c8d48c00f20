"""How each stage grows with the swarm: a free-space crossing for N = 100 ... 3000 robots.

The crossing: a free 300 x 200 m map, N robots sampled around (50, 100) with
sigma = 12 sqrt(N / 1000) m (so the density does not change with N), goal (250, 100),
k = 7, every other setting the default, simulation off. By default the continuous stage is
off (``smoothing.enabled = false``; a discrete-only run prunes waypoints the paper's way);
``--continuous`` adds it (safe regions, receding horizon, certification: its parts
``regions``, ``smoothing``, ``checking`` are timed too) and writes ``scale_continuous.*``.

Each run is a separate process (so its peak resident memory is its own) that plans,
then writes the outputs (``result.json``, ``discrete_paths.csv``, figures) to a
temporary folder. Per run: MRF steps, seconds per stage (scenario, discrete, pruning,
outputs; the discrete stage's per-step parts: graph, cliques, labels, energy,
optimizer, and the final safety check), milliseconds per MRF step, peak RSS. With
``--baseline REF`` the same runs are made with the code of git revision REF (default
``main``; extracted to a temporary folder and put first on the child's path) for
N <= ``--baseline-max``, in the same session, so the table compares old and new on the
same machine and load. The fitted exponent of each stage is the least-squares slope of
log(time) against log(N) over the new runs (written to ``*_exponents.csv``), with the
milliseconds per MRF step and its parts.

    python experiments/bench/scale.py [--sizes 100,300,1000,3000] [--baseline main] [--baseline-max 300]
        [--continuous] [--workers W] [--out experiments/bench/results/scale.csv]
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from baseline_code import extract, run_child, use

RESULTS = Path(__file__).parent / "results"
#: Stages of a whole run, in seconds (the continuous stage's with --continuous).
STAGES = ("scenario", "discrete", "pruning", "check", "outputs")
CONTINUOUS = ("regions", "smoothing", "checking")
#: Parts of one MRF step, in milliseconds (means over the run's steps).
STEP_PARTS = ("graph", "cliques", "labels", "energy", "optimizer")


def overrides(n: int, continuous: bool = False) -> list[str]:
    """The crossing for ``n`` robots as ``--set`` overrides of the default config."""
    sigma = 12.0 * math.sqrt(n / 1000.0)
    return [
        'scenario.map={kind="free", size=[300, 200]}',
        f"scenario.start={{center=[50.0, 100.0], n_robots={n}, sigma={sigma:.6g}, seed=0}}",
        "scenario.goal=[250, 100]",
        "interaction.k=7",
        f"smoothing.enabled={'true' if continuous else 'false'}",
        "simulation.enabled=false",
    ]


def child(n: int, code: str | None, continuous: bool = False, workers: int | None = None) -> None:
    """Plan the crossing, write the outputs, print one JSON line (runs in its own process)."""
    use(code)
    import resource

    import mrfswarm
    try:
        from mrfswarm.discrete.safety import discrete_violations
    except ImportError:  # the baseline revision's layout
        from mrfswarm.safety import discrete_violations
    from mrfswarm.outputs import write_outputs
    from mrfswarm.pipeline import plan

    cfg = mrfswarm.load_config(None, overrides(n, continuous))
    t0 = time.perf_counter()
    r = plan(cfg, progress=False, **({"workers": workers} if workers else {}))
    total = time.perf_counter() - t0
    t0 = time.perf_counter()
    bad = discrete_violations(r.discrete.paths, r.scenario.grid.free)
    check = time.perf_counter() - t0
    with tempfile.TemporaryDirectory() as out:
        t0 = time.perf_counter()
        write_outputs(r, Path(out))
        outputs = time.perf_counter() - t0
    steps = r.discrete.n_steps
    print(json.dumps({
        "N": n, "steps": steps, "plan_s": total, "violations": len(bad), "reached_goal": r.metrics.reached_goal,
        **{f"{s}_s": float(r.timings_s.get(s, 0.0)) for s in ("scenario", "discrete", "pruning", *CONTINUOUS)},
        "makespan_s": None if r.continuous is None else r.continuous.makespan_s,
        "check_s": check, "outputs_s": outputs,
        **{f"{s}_ms": 1e3 * float(np.mean(r.discrete.timings[s])) if steps else 0.0 for s in STEP_PARTS},
        "step_ms": 1e3 * float(r.timings_s.get("discrete", 0.0)) / max(1, steps),
        "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
    }))


def run(n: int, code: Path | None, continuous: bool = False, workers: int | None = None) -> dict:
    extra = (["--continuous"] if continuous else []) + (["--workers", str(workers)] if workers else [])
    return run_child(Path(__file__), ["--child", str(n), *extra], code)


def exponent(ns: list[int], ts: list[float]) -> float:
    ok = [(n, t) for n, t in zip(ns, ts) if t > 0]
    if len(ok) < 2:
        return float("nan")
    x, y = np.log([n for n, _ in ok]), np.log([t for _, t in ok])
    return float(np.polyfit(x, y, 1)[0])


def figure(rows: list[dict], slopes: dict[str, float], path: Path, stages: tuple[str, ...] = STAGES,
           base: str = "") -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.8), dpi=110)
    for i, s in enumerate(stages):
        color = plt.get_cmap("tab10")(i)
        for kind, mark, ls in (("new", "o", "-"), ("baseline", "s", ":")):
            pts = [(r["N"], r[f"{s}_s"]) for r in rows if r["code"] == kind and r[f"{s}_s"] > 0]
            if pts:
                slope = f" (slope {slopes[s]:.2f})" if np.isfinite(slopes[s]) else ""  # one size: no slope
                label = f"{s}{slope}" if kind == "new" else None
                ax.plot(*zip(*pts), ls, marker=mark, color=color, label=label, ms=5)
    ns = sorted({r["N"] for r in rows})
    ref = [r for r in rows if r["code"] == "new"]
    if ref:
        t0 = max(r["discrete_s"] for r in ref if r["N"] == ns[0])
        ax.plot(ns, [t0 * n / ns[0] for n in ns], "-", color="0.7", lw=3, alpha=0.5, label="linear", zorder=0)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("robots N")
    ax.set_ylabel("seconds")
    what = "both stages" if "smoothing" in stages else "discrete stage only"
    has_base = any(r["code"] == "baseline" for r in rows)
    ax.set_title(f"free-space crossing, {what}" + (f" (dotted: {base})" if base and has_base else ""))
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    print(f"wrote {path}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", default="100,300,1000,3000")
    ap.add_argument("--baseline", default="main", help="git revision of the baseline ('' for none)")
    ap.add_argument("--baseline-max", type=int, default=300, help="largest N the baseline is run for")
    ap.add_argument("--out", type=Path, default=None, help="default: results/scale.csv (scale_continuous.csv)")
    ap.add_argument("--continuous", action="store_true", help="also run the continuous stage")
    ap.add_argument("--workers", type=int, default=None, help="processes for the continuous stage (default: cores)")
    ap.add_argument("--child", type=int, help=argparse.SUPPRESS)
    ap.add_argument("--code", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child is not None:
        child(args.child, args.code, args.continuous, args.workers)
        return
    stages = (*STAGES, *CONTINUOUS) if args.continuous else STAGES
    if args.out is None:
        args.out = RESULTS / ("scale_continuous.csv" if args.continuous else "scale.csv")
    sizes = [int(v) for v in args.sizes.split(",")]
    rows = []
    cols = ("steps", *[f"{s}_s" for s in stages], "step_ms", *[f"{s}_ms" for s in STEP_PARTS], "peak_rss_mb")
    print(f"{'N':>5} {'code':>8} " + " ".join(f"{c:>12}" for c in cols), flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        base = extract(args.baseline, Path(tmp)) if args.baseline else None
        for n in sizes:
            runs = [("new", None)] + ([("baseline", base)] if base is not None and n <= args.baseline_max else [])
            for kind, code in runs:
                r = {"code": kind, **run(n, code, args.continuous, args.workers)}
                rows.append(r)
                print(f"{n:>5} {kind:>8} " + " ".join(f"{r[c]:>12.3f}" if isinstance(r[c], float) else f"{r[c]:>12}"
                                                     for c in cols), flush=True)
    new = [r for r in rows if r["code"] == "new"]
    slopes = {s: exponent([r["N"] for r in new], [r[f"{s}_s"] for r in new]) for s in stages}
    slopes.update({s: exponent([r["N"] for r in new], [r[f"{s}_ms"] for r in new]) for s in ("step", *STEP_PARTS)})
    if len({r["N"] for r in new}) < 2:
        print("fitted exponent of time in N: needs two sizes or more (--sizes)")
    else:
        print("fitted exponent of time in N (new): " + ", ".join(f"{s} {v:.2f}" for s, v in slopes.items()))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    with open(args.out, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]) + ["baseline_ref"])
        w.writeheader()
        for r in rows:
            w.writerow({**r, "baseline_ref": args.baseline if r["code"] == "baseline" else ""})
    exps = args.out.with_name(args.out.stem + "_exponents.csv")
    with open(exps, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["stage", "exponent", "sizes"])
        for s, v in slopes.items():
            w.writerow([s, round(v, 3), args.sizes])
    print(f"wrote {args.out} and {exps}")
    figure(rows, slopes, args.out.with_suffix(".png"), stages, args.baseline)


if __name__ == "__main__":
    main()
