"""Navigation study: does the swarm reach its goal on generated maps? (Beyond the paper.)

32 generated maps (:mod:`mrfswarm.maps.synthetic`: rooms, U/C traps, forests, mazes;
seeds 1-8 of each class, the first four of each being ``experiments/maps/``), each with
5, 20 and 50 robots, start seeds 0 and 1, planned by the discrete stage only
(``smoothing.enabled = false``: the question is where the MRF steps take the swarm; the
continuous stage follows the discrete paths). Variants:

``default``
    The default config (the README's defaults beyond the paper: geodesic goal field, Gamma = 2,
    trimmed label sets, ``mrf.contested = "auto"``, following, the end on arrival, the escalation,
    patience on the static field sum too).
``euclidean``
    The default with the paper's straight-line goal field.
``paper``
    The paper's rules throughout, as the paper's scenario configs set them (``euclidean``,
    Gamma = 5, ``mrf.contested = "nearest"``, ``mrf.progress = "energy"``, no trimming, no
    following, no end on arrival, no escalation, the paths as the MRF made them).
``geodesic+nearest``, ``geodesic+energy``
    The default with one of its two other rules set back to the paper's: what each
    contributes.
``<method>``, ``<method>+euclidean``
    The default (or the Euclidean field) with another MRF method instead of ICM
    (start seed 0 only: the slower methods take ~5x ICM's time).

A run succeeds when every robot ends in the goal region (free-path distance to the goal
at most ``goal_radius`` + the radius holding 4 free cells per robot) and the swarm is
cohesive (every robot's nearest neighbour within 1.5 d_min). Also recorded: the first
step with every robot in the goal region, MRF steps, the minimum separation (during
moves included), planning time (scenario with its Dijkstra searches, plus the discrete
stage), and the robots' stop reasons.

Writes ``OUT/navigation.csv`` (one row per run), ``OUT/navigation.md`` (the tables) and
``OUT/navigation.png``.

    PYTHONPATH=. python experiments/navigation.py --out paper_figs           # 1728 runs, 10-40 min on 2 shared cores (as loaded)
    PYTHONPATH=. python experiments/navigation.py --quick --out /tmp/nav     # 8 maps, ICM variants, 240 runs, ~2.5 min
    PYTHONPATH=. python experiments/navigation.py --figure-only              # the figure again from navigation.csv, ~20 s
"""

from __future__ import annotations

import argparse
import csv
import importlib.util
import statistics
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
GENERATE = ROOT / "experiments" / "maps" / "generate.py"

SEEDS = range(1, 9)
ROBOTS = (5, 20, 50)
START_SEEDS = (0, 1)
#: variant -> (--set overrides, MRF method, start seeds)
ICM_VARIANTS: dict[str, tuple[tuple[str, ...], str]] = {
    "default": ((), "icm"),
    "euclidean": (('goal_potential.distance="euclidean"',), "icm"),
    "paper": (('goal_potential.distance="euclidean"', 'mrf.contested="nearest"', 'mrf.progress="energy"',
               "obstacle_potential.gamma=5", "mrf.trim_backward=false", "mrf.follow=false", "mrf.arrival=false",
               "mrf.merge_waits=false", "mrf.drop_loops=false", "mrf.straighten=false", 'mrf.escalation="none"'),
              "icm"),
    "geodesic+nearest": (('mrf.contested="nearest"',), "icm"),
    "geodesic+energy": (('mrf.progress="energy"',), "icm"),
}
METHODS = ("gibbs", "bp", "trws", "lazy_flipper")
COLUMNS = ["variant", "method", "map", "kind", "seed", "n_robots", "start_seed", "success", "at_goal", "cohesive",
           "steps_to_goal", "mrf_steps", "stop_reason", "trapped", "stalled", "separated", "min_separation_m",
           "max_nearest_neighbour_m", "planning_s", "field_s", "goal_region_m"]


def _generate_module():
    spec = importlib.util.spec_from_file_location("generate_maps", GENERATE)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def variants(quick: bool) -> dict[str, tuple[tuple[str, ...], str, tuple[int, ...]]]:
    out = {k: (o, m, START_SEEDS) for k, (o, m) in ICM_VARIANTS.items()}
    if not quick:
        for m in METHODS:
            out[m] = ((), m, (0,))
            out[f"{m}+euclidean"] = (('goal_potential.distance="euclidean"',), m, (0,))
    return out


def write_configs(folder: Path, seeds, robots) -> list[tuple[str, str, int, int, Path]]:
    """Every (map, N) config, written with the maps into ``folder``; (name, kind, seed, N, path) each."""
    from mrfswarm.maps import save_movingai
    from mrfswarm.maps.synthetic import GENERATORS, generate

    gen = _generate_module()
    out = []
    for kind in GENERATORS:
        for seed in seeds:
            m = generate(kind, seed)
            save_movingai(m.grid, folder / f"{m.name}.map")
            for n in robots:
                p = folder / f"{m.name}_n{n}.toml"
                p.write_text(gen.config_text(m, n))
                out.append((m.name, kind, seed, n, p))
    return out


def run_case(args: tuple) -> tuple[dict, np.ndarray | None]:
    """One run; returns its row (and the paths when asked, for the figure)."""
    from mrfswarm.config import load_config
    from mrfswarm.discrete.planner import SEPARATION_FACTOR, plan_discrete
    from mrfswarm.discrete.robot_outcomes import robot_outcomes
    from mrfswarm.metrics import min_separation
    from mrfswarm.pipeline import mrf_options
    from mrfswarm.scenario import build_scenario

    variant, overrides, method, name, kind, seed, n, start_seed, path, keep_paths = args
    cfg = load_config(path, ["smoothing.enabled=false", f"mrf.method={method}", *overrides])
    t0 = time.perf_counter()
    scn = build_scenario(cfg, seed=start_seed)
    t1 = time.perf_counter()
    plan = plan_discrete(scn.discrete_problem(), method=method, max_steps=cfg.mrf.max_steps, tol=cfg.mrf.tol,
                         patience=cfg.mrf.patience, options=mrf_options(cfg, start_seed), progress=cfg.mrf.progress,
                         arrival=cfg.mrf.arrival)
    t2 = time.perf_counter()
    sep = SEPARATION_FACTOR * scn.morse.d_min
    robots = robot_outcomes(plan.paths[-1], scn.grid.free, scn.static, cfg.mrf.order, scn.grid.resolution, sep,
                            plan.stop_reason, scn.distances.path, scn.goal_region_radius)
    d = scn.distances.path
    inside = np.array([np.all(d[p[:, 0], p[:, 1]] <= scn.goal_region_radius) for p in plan.paths])
    at_goal = sum(bool(r.at_goal) for r in robots)
    max_nn = max(r.nearest_neighbour for r in robots)
    reasons = [r.stop_reason for r in robots]
    row = {
        "variant": variant, "method": method, "map": name, "kind": kind, "seed": seed, "n_robots": n,
        "start_seed": start_seed, "at_goal": at_goal, "cohesive": bool(max_nn <= sep),
        "success": bool(at_goal == n and max_nn <= sep),
        "steps_to_goal": int(np.argmax(inside)) if inside.any() else "",
        "mrf_steps": plan.n_steps, "stop_reason": plan.stop_reason,
        "trapped": reasons.count("trapped"), "stalled": reasons.count("stalled") + reasons.count("max_steps"),
        "separated": sum(r.separated for r in robots),
        "min_separation_m": round(min_separation(plan.paths, scn.downwash) * scn.grid.resolution, 4),
        "max_nearest_neighbour_m": round(max_nn, 3), "planning_s": round(t2 - t0, 4), "field_s": round(t1 - t0, 4),
        "goal_region_m": round(scn.goal_region_radius, 3),
    }
    return row, (plan.paths if keep_paths else None)


#: (map, N, start seed) whose paths the figure draws, with the default and the Euclidean field.
EXAMPLES = (("trap_01", 20, 0), ("rooms_02", 20, 0))
#: What the figure's example panels draw, by variant: the ``euclidean`` variant keeps the default's rules
#: (only its goal field is the paper's); the paper's rules throughout are the ``paper`` variant, not drawn.
EXAMPLE_LABELS = {"euclidean": "Euclidean field, default rules", "default": "geodesic field (default)"}


def run_all(quick: bool, workers: int) -> tuple[list[dict], dict]:
    seeds = range(1, 3) if quick else SEEDS
    with tempfile.TemporaryDirectory() as tmp:
        configs = write_configs(Path(tmp), seeds, ROBOTS)
        tasks = []
        for variant, (overrides, method, starts) in variants(quick).items():
            for name, kind, seed, n, path in configs:
                for s in starts:
                    keep = variant in ("default", "euclidean") and (name, n, s) in EXAMPLES
                    tasks.append((variant, overrides, method, name, kind, seed, n, s, str(path), keep))
        rows, paths = [], {}
        t0 = time.perf_counter()
        with ProcessPoolExecutor(max_workers=workers) as pool:
            for i, (row, p) in enumerate(pool.map(run_case, tasks, chunksize=2)):
                rows.append(row)
                if p is not None:
                    paths[(row["variant"], row["map"], row["n_robots"], row["start_seed"])] = p
                if (i + 1) % 50 == 0 or i + 1 == len(tasks):
                    print(f"{i + 1}/{len(tasks)} runs, {time.perf_counter() - t0:.0f} s", file=sys.stderr, flush=True)
    return rows, paths


def read_rows(path: Path) -> list[dict]:
    """The rows of a study's ``navigation.csv``, typed as :func:`run_case` returns them."""
    ints = ("seed", "n_robots", "start_seed", "at_goal", "mrf_steps", "trapped", "stalled", "separated")
    floats = ("min_separation_m", "max_nearest_neighbour_m", "planning_s", "field_s", "goal_region_m")
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    for r in rows:
        r.update({k: int(r[k]) for k in ints})
        r.update({k: float(r[k]) for k in floats})
        r.update({k: r[k] == "True" for k in ("success", "cohesive")})
        r["steps_to_goal"] = int(r["steps_to_goal"]) if r["steps_to_goal"] else ""
    return rows


def example_runs() -> tuple[list[dict], dict]:
    """The runs whose paths the figure draws (:data:`EXAMPLES`, :data:`EXAMPLE_LABELS`), planned again."""
    from mrfswarm.maps import save_movingai
    from mrfswarm.maps.synthetic import generate

    gen = _generate_module()
    rows, paths = [], {}
    with tempfile.TemporaryDirectory() as tmp:
        for name, n, s in EXAMPLES:
            kind, seed = name.rsplit("_", 1)
            m = generate(kind, int(seed))
            save_movingai(m.grid, Path(tmp) / f"{m.name}.map")
            path = Path(tmp) / f"{m.name}_n{n}.toml"
            path.write_text(gen.config_text(m, n))
            for v in EXAMPLE_LABELS:
                overrides, method = ICM_VARIANTS[v]
                row, p = run_case((v, overrides, method, name, kind, int(seed), n, s, str(path), True))
                rows.append(row)
                paths[(v, name, n, s)] = p
    return rows, paths


def _rate(rows: list[dict]) -> str:
    ok = sum(r["success"] for r in rows)
    return f"{100 * ok / len(rows):.0f} % ({ok}/{len(rows)})" if rows else "-"


def _median(values) -> str:
    v = [float(x) for x in values if x != ""]
    return f"{statistics.median(v):.0f}" if v else "-"


def tables(rows: list[dict]) -> str:
    """The Markdown summary."""
    from mrfswarm.maps.synthetic import GENERATORS

    kinds = list(GENERATORS)
    names = list(dict.fromkeys(r["variant"] for r in rows))
    maps = sorted({r["map"] for r in rows})
    lines = [
        f"{len(maps)} generated maps ({', '.join(f'{sum(m.startswith(k) for m in maps)} {k}' for k in kinds)}), "
        f"{len(set(r['n_robots'] for r in rows))} swarm sizes ({', '.join(str(n) for n in ROBOTS)} robots), discrete "
        "stage only. Success: every robot in the goal region and every nearest neighbour within 1.5 d_min.",
        "",
        "| variant | MRF | runs | success | " + " | ".join(kinds) + " | robots at goal | trapped robots | "
        "stalled robots | steps to goal (median) | MRF steps (median) | min separation (m) | planning time (median s) |",
        "|" + "---|" * (12 + len(kinds) - 1),
    ]
    for v in names:
        rs = [r for r in rows if r["variant"] == v]
        n_rob = sum(r["n_robots"] for r in rs)
        lines.append(
            f"| {v} | {rs[0]['method']} | {len(rs)} | {_rate(rs)} | "
            + " | ".join(_rate([r for r in rs if r["kind"] == k]) for k in kinds)
            + f" | {100 * sum(r['at_goal'] for r in rs) / n_rob:.1f} % | {sum(r['trapped'] for r in rs)} | "
            f"{sum(r['stalled'] for r in rs)} | {_median(r['steps_to_goal'] for r in rs)} | "
            f"{_median(r['mrf_steps'] for r in rs)} | {min(r['min_separation_m'] for r in rs):.2f} | "
            f"{statistics.median(r['planning_s'] for r in rs):.2f} |")
    lines += ["", "By swarm size (success rate):", "",
              "| variant | " + " | ".join(f"N = {n}" for n in ROBOTS) + " |", "|---|" + "---|" * len(ROBOTS)]
    for v in names:
        rs = [r for r in rows if r["variant"] == v]
        lines.append(f"| {v} | " + " | ".join(_rate([r for r in rs if r["n_robots"] == n]) for n in ROBOTS) + " |")
    d = [r for r in rows if r["variant"] == "default"]
    if d:
        lines += ["", "Default, by swarm size: median planning time (s) and field time (s, the two Dijkstra "
                  "searches and the blur, once per scenario):", "",
                  "| N | planning s | field s | steps to goal |", "|---|---|---|---|"]
        for n in ROBOTS:
            rs = [r for r in d if r["n_robots"] == n]
            lines.append(f"| {n} | {statistics.median(r['planning_s'] for r in rs):.2f} | "
                         f"{statistics.median(r['field_s'] for r in rs):.3f} | {_median(r['steps_to_goal'] for r in rs)} |")
    return "\n".join(lines) + "\n"


def _label_bars(ax) -> None:
    """Each bar's height on it (a 0 % bar is otherwise invisible)."""
    for c in ax.containers:
        ax.bar_label(c, fmt="%.0f", fontsize=7, padding=1)


def figure(rows: list[dict], paths: dict, path: Path) -> Path:
    from mrfswarm import plots
    from mrfswarm.maps.synthetic import GENERATORS, generate

    plt = plots._plt()
    kinds = list(GENERATORS)
    names = list(dict.fromkeys(r["variant"] for r in rows))
    icm = [v for v in names if v in ICM_VARIANTS]
    with plots.paper_style():
        fig = plt.figure(figsize=(16, 10), layout="constrained")
        gs = fig.add_gridspec(2, 4, height_ratios=[1, 1.15])
        ax = fig.add_subplot(gs[0, :2])
        w = 0.8 / len(icm)
        for j, v in enumerate(icm):
            rates = [100 * np.mean([r["success"] for r in rows if r["variant"] == v and r["kind"] == k]) for k in kinds]
            ax.bar(np.arange(len(kinds)) + (j - (len(icm) - 1) / 2) * w, rates, w, label=v)
        ax.set_xticks(np.arange(len(kinds)), kinds)
        ax.set_ylabel("success rate [%]")
        ax.set_ylim(0, 105)
        ax.set_title("(a) ICM: goal field and rules, by map class")
        ax.legend(fontsize=8, ncols=len(icm), loc="upper center", bbox_to_anchor=(0.5, -0.08))
        _label_bars(ax)
        ax = fig.add_subplot(gs[0, 2])
        methods = ["icm", *[m for m in METHODS if m in names]]
        for j, field in enumerate(("geodesic", "euclidean")):
            rates = []
            for m in methods:
                v = ("default" if field == "geodesic" else "euclidean") if m == "icm" else (
                    m if field == "geodesic" else f"{m}+euclidean")
                rs = [r for r in rows if r["variant"] == v and r["start_seed"] == 0]
                rates.append(100 * np.mean([r["success"] for r in rs]) if rs else np.nan)
            ax.bar(np.arange(len(methods)) + (j - 0.5) * 0.4, rates, 0.4, label=f"{field} field")
        ax.set_xticks(np.arange(len(methods)), methods, rotation=20)
        ax.set_ylim(0, 105)
        ax.set_ylabel("success rate [%]")
        ax.set_title("(b) MRF methods (start seed 0)")
        ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.18), ncols=2)
        _label_bars(ax)
        ax = fig.add_subplot(gs[0, 3])
        d = [r for r in rows if r["variant"] == "default" and r["steps_to_goal"] != ""]
        for j, k in enumerate(kinds):
            xs = [ROBOTS.index(r["n_robots"]) + 0.15 * (j - 1.5) for r in d if r["kind"] == k]
            ax.scatter(xs, [r["steps_to_goal"] for r in d if r["kind"] == k], s=14, label=k, alpha=0.8)
        ax.set_xticks(range(len(ROBOTS)), [str(n) for n in ROBOTS])
        ax.set_xlabel("robots")
        ax.set_ylabel("MRF steps until all at the goal")
        ax.set_title("(c) default: steps to the goal")
        ax.legend(fontsize=8)
        col = 0
        for name, n, s in EXAMPLES:
            kind, seed = name.rsplit("_", 1)
            m = generate(kind, int(seed))
            for v in EXAMPLE_LABELS:
                ax = fig.add_subplot(gs[1, col])
                col += 1
                P = paths.get((v, name, n, s))
                ax.imshow(m.occupied.T, origin="lower", cmap="Greys", vmin=0, vmax=1.6, interpolation="nearest")
                if P is not None:
                    colors = plots._robot_colors(P.shape[1])
                    for i in range(P.shape[1]):
                        ax.plot(P[:, i, 0], P[:, i, 1], lw=0.7, color=colors[i], alpha=0.7)
                    ax.scatter(P[-1, :, 0], P[-1, :, 1], s=10, color="k", zorder=3)
                    row = next(r for r in rows if r["variant"] == v and r["map"] == name and r["n_robots"] == n
                               and r["start_seed"] == s)
                    status = f"{row['at_goal']}/{n} at goal, {row['trapped']} trapped"
                else:
                    status = "not run"
                ax.plot(*m.start, marker="s", color="tab:blue", ms=7, zorder=4)
                ax.plot(*m.goal, marker="*", color="tab:red", ms=13, zorder=4)
                ax.set_title(f"({chr(ord('d') + col - 1)}) {name}, {EXAMPLE_LABELS[v]}\n{status}", fontsize=9)
                ax.set_xticks([])
                ax.set_yticks([])
        plots.save_figure(fig, path)
    return path


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, default=ROOT / "paper_figs", help="output folder (default: paper_figs)")
    ap.add_argument("--quick", action="store_true", help="8 maps, the ICM variants only")
    ap.add_argument("--workers", type=int, default=2, help="processes (default 2)")
    ap.add_argument("--figure-only", action="store_true",
                    help="redraw OUT/navigation.png from OUT/navigation.csv, planning again only the example runs "
                    "it draws (seconds); refused if their robots at the goal or trapped differ from the CSV's")
    args = ap.parse_args(argv)
    if args.workers < 1:
        ap.error(f"--workers {args.workers}: must be >= 1")
    if args.figure_only:
        return _redraw(args.out)
    args.out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    rows, paths = run_all(args.quick, args.workers)
    with open(args.out / "navigation.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=COLUMNS)
        w.writeheader()
        w.writerows(rows)
    md = tables(rows)
    (args.out / "navigation.md").write_text(
        "# Navigation on generated maps (beyond the paper)\n\n"
        "Written by `PYTHONPATH=. python experiments/navigation.py" + (" --quick" if args.quick else "")
        + "` (see its docstring for the variants); one row per run in `navigation.csv`, the figure is "
        "`navigation.png`.\n\n" + md)
    figure(rows, paths, args.out / "navigation.png")
    print(md)
    print(f"{len(rows)} runs in {time.perf_counter() - t0:.0f} s -> {args.out}", file=sys.stderr)
    return 0


def _redraw(out: Path) -> int:
    """``--figure-only``: the figure from the study's CSV and the example runs planned again."""
    csv_path = out / "navigation.csv"
    if not csv_path.is_file():
        print(f"navigation.py: error: --figure-only needs {csv_path}, the study's table: run the study", file=sys.stderr)
        return 2
    rows = read_rows(csv_path)
    fresh, paths = example_runs()
    for f in fresh:
        old = next((r for r in rows if all(r[k] == f[k] for k in ("variant", "map", "n_robots", "start_seed"))), None)
        now = {k: f[k] for k in ("at_goal", "trapped", "steps_to_goal", "mrf_steps")}
        then = {k: old[k] for k in now} if old else None
        # the panel prints at_goal and trapped from the CSV beside the paths planned now: they must agree
        if then is None or any(then[k] != now[k] for k in ("at_goal", "trapped")):
            print(f"navigation.py: error: {f['variant']} on {f['map']} with {f['n_robots']} robots now plans "
                  f"{now}, {csv_path} says {then or 'nothing'}: run the whole study", file=sys.stderr)
            return 2
        if then != now:
            print(f"navigation.py: warning: {f['variant']} on {f['map']} with {f['n_robots']} robots now plans "
                  f"{now}, {csv_path} says {then}: the panel draws the paths planned now", file=sys.stderr)
    figure(rows, paths, out / "navigation.png")
    print(f"{out / 'navigation.png'}: redrawn from {csv_path} and {len(fresh)} example runs", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
