"""Flight quality with default settings, on maps of our own, against an earlier revision in the same run.

Per case and variant (``default``, ``refined`` = ``smoothing.time_refinement = true``, by the
multiplier scaling, ``refined_nlp`` = the same by the NLP backend, Ipopt),
flight simulation off, what a user feels:

- ``bound``: makespan over its dynamic lower bound (the longest shortest free path,
  8-connected without corner cutting, from a robot's start cell to its final cell, at
  v_max; :mod:`mrfswarm.flight_quality`);
- ``stops``: stops per robot (slower than 0.05 m/s strictly inside its flight), mean and max;
- ``speed``: mean speed over robots (m/s);
- ``at goal``: robots in the goal region at the end;
- ``steps``: MRF steps; ``plan_s``: the time of :func:`~mrfswarm.pipeline.plan` alone; ``run_s``: the whole
  run's wall time (importing the package, planning, writing every output), what a user of ``mrfswarm run`` waits.

The same measurement code (this file and the working tree's ``mrfswarm.flight_quality``,
imported by path) scores the baseline's trajectories, run from ``git archive`` of
``--baseline`` in a child process, so the columns compare plans, not metrics.

Cases (deterministic maps built here; 1 m cells unless said):

- ``corridor``: the paper's corridor, 5 robots (``experiments/corridor.toml``, its paper rules);
- ``doorway``: a 30 x 20 room split by a wall with a 3-cell doorway, 5 robots;
- ``forest``: ``experiments/maps/forest_01``, 10 robots, k = 7;
- ``rooms``: ``experiments/maps/rooms_01``, 5 robots;
- ``trap``: ``experiments/maps/trap_01`` (U-shaped), 5 robots;
- ``open50``: 50 robots across an open 60 x 60 field, k = 7;
- ``clutter40``: 40 robots on 64 x 64 with 10 % random single-cell obstacles, k = 7; ``clutter40@S``
  (``--cases`` only) the same on the map of seed S (``clutter40`` is seed 1; 1-7 are the seven maps of the docs);
- ``aisles30``: 30 robots through a warehouse of shelves with 2-cell aisles, k = 7;
- ``arena8``: 8 robots in a 6 x 3.5 m arena of 0.25 m cells (robot radius 0.1 m, v_max 1 m/s);
- ``big200`` (``--cases`` only): 200 robots on 128 x 128 with 15 % obstacles;
- ``cross1000`` (``--cases`` only): 1000 robots crossing 240 m of open field;
- ``funnel20``, ``halls50`` (``--cases`` only): queues at gaps, from a new-user tour (twenty-third session): 20
  robots into walls converging on a one-cell gap (40 x 30), 50 robots between two halls through three 2-cell
  corridors in an 8-cell wall (56 x 40); k = 7;
- ``field3d``, ``window3d``, ``columns3d`` (``--cases`` only): the 3-D scenarios of ``experiments/``
  (40, 12 and 16 robots on voxel maps, downwash 2; the bound on the 26-connected voxel graph);
- ``cross300`` (``--cases`` only): 300 robots crossing 110 m of open field (the big swarm's windows, quicker).

    python experiments/bench/flight_quality.py [--cases ...] [--variants default,refined,refined_nlp]
        [--baseline REV] [--baseline-variants default] [--repeat N] [--out experiments/bench/results/flight_quality.csv]

``--repeat N`` plans every case N times, the rounds interleaved (each round runs every code and variant of the
case once), and the cost lines give the median over the rounds of the refined run's time over the default's in
the same round: the machine is shared and noisy, and a ratio taken within a round holds better than one
timing. The flights of the rounds must be the same (the planning is deterministic); a round that differs is
reported.
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from baseline_code import ROOT, drop_unknown_keys, extract, run_child, use

EXP = ROOT / "experiments"
RESULTS = Path(__file__).parent / "results"
DEFAULT_CASES = "corridor,doorway,forest,rooms,trap,open50,clutter40,aisles30,arena8"
VARIANTS = {"default": [], "refined": ["smoothing.time_refinement=true"],
            "refined_nlp": ["smoothing.time_refinement=true", "smoothing.refinement=nlp"]}


def _rows(occ) -> list[str]:
    """(W, H) bool to ``ascii`` rows: row y of the file holds cells (x, y), as the loader reads it."""
    W, H = occ.shape
    return ["".join("@" if occ[x, y] else "." for x in range(W)) for y in range(H)]


def _clear(occ, centre, radius: float) -> None:
    W, H = occ.shape
    import numpy as np

    xs, ys = np.meshgrid(np.arange(W), np.arange(H), indexing="ij")
    occ[(xs - centre[0]) ** 2 + (ys - centre[1]) ** 2 <= radius**2] = False


def _connected_to(occ, goal):
    from scipy import ndimage

    lab, _ = ndimage.label(~occ)
    keep = lab == lab[goal]
    out = occ.copy()
    out[~keep] = True
    return out


def _random_field(W: int, H: int, density: float, seed: int, start, goal, clear: float):
    import numpy as np

    rng = np.random.default_rng(seed)
    occ = rng.random((W, H)) < density
    occ[0, :] = occ[-1, :] = occ[:, 0] = occ[:, -1] = False
    _clear(occ, start, clear)
    _clear(occ, goal, clear)
    return _connected_to(occ, tuple(goal))


def case_config(case: str) -> tuple[dict, Path]:
    """The config table of a case and the folder its paths are relative to."""
    import tomllib

    import numpy as np

    if case == "corridor":
        return tomllib.loads((EXP / "corridor.toml").read_text()), EXP
    if case in ("field3d", "window3d", "columns3d"):  # voxel maps with downwash 2 (issue 20)
        return tomllib.loads((EXP / f"{case}.toml").read_text()), EXP
    if case in ("forest", "rooms", "trap"):
        name = {"forest": "forest_01", "rooms": "rooms_01", "trap": "trap_01"}[case]
        data = tomllib.loads((EXP / "maps" / f"{name}.toml").read_text())
        if case == "forest":
            data["scenario"]["start"]["n_robots"] = 10
            data["scenario"]["start"]["sigma"] = 1.5
            data["interaction"]["k"] = 7
        return data, EXP / "maps"
    if case == "doorway":
        occ = np.zeros((30, 20), dtype=bool)
        occ[15, :] = True
        occ[15, 9:12] = False
        scn = {"map": {"kind": "ascii", "rows": _rows(occ)},
               "start": {"center": [6, 10], "n_robots": 5, "sigma": 1.0, "seed": 0}, "goal": [25, 10]}
        return {"scenario": scn, "interaction": {"k": 3}}, EXP
    if case == "open50":
        scn = {"map": {"kind": "free", "size": [60, 60]},
               "start": {"center": [10, 10], "n_robots": 50, "sigma": 3.0, "seed": 0}, "goal": [50, 50]}
        return {"scenario": scn, "interaction": {"k": 7}}, EXP
    if case == "clutter40" or case.startswith("clutter40@"):
        seed_text = case.partition("@")[2] or "1"
        if not seed_text.isdigit():
            raise SystemExit(f"case {case!r}: the seed after '@' must be a whole number")
        seed = int(seed_text)
        occ = _random_field(64, 64, 0.10, seed, (8, 8), (55, 55), 5)
        scn = {"map": {"kind": "ascii", "rows": _rows(occ)},
               "start": {"center": [8, 8], "n_robots": 40, "sigma": 2.5, "seed": 0}, "goal": [55, 55]}
        return {"scenario": scn, "interaction": {"k": 7}}, EXP
    if case == "aisles30":
        occ = np.zeros((48, 40), dtype=bool)
        for x0 in range(12, 36, 4):  # shelves 2 cells wide, aisles 2 cells wide
            occ[x0:x0 + 2, 6:34] = True
        scn = {"map": {"kind": "ascii", "rows": _rows(occ)},
               "start": {"center": [5, 20], "n_robots": 30, "sigma": 2.0, "seed": 0}, "goal": [42, 20]}
        return {"scenario": scn, "interaction": {"k": 7}}, EXP
    if case == "arena8":
        occ = np.zeros((24, 14), dtype=bool)  # 6 x 3.5 m at 0.25 m
        occ[11:13, 0:5] = True  # two pillars in the middle
        occ[11:13, 9:14] = True
        scn = {"map": {"kind": "ascii", "rows": _rows(occ), "resolution": 0.25},
               "start": {"positions": [[0.5, y] for y in (0.75, 1.5, 2.25, 3.0)] + [[1.0, y] for y in (0.75, 1.5, 2.25, 3.0)]},
               "goal": [5.25, 1.75], "robot_radius": 0.1, "goal_radius": 0.75}
        return {"scenario": scn, "interaction": {"k": 3}, "smoothing": {"v_max": 1.0}}, EXP
    if case == "big200":
        occ = _random_field(128, 128, 0.15, 2, (12, 12), (115, 115), 9)
        scn = {"map": {"kind": "ascii", "rows": _rows(occ)},
               "start": {"center": [12, 12], "n_robots": 200, "sigma": 5.0, "seed": 0}, "goal": [115, 115]}
        return {"scenario": scn, "interaction": {"k": 7}}, EXP
    if case == "funnel20":  # a tour's queue: walls converging on a one-cell gap (twenty-third session)
        occ = np.zeros((40, 30), dtype=bool)
        for x in range(12, 20):
            half = max(15 - (x - 12) * 2, 0)
            occ[x, :max(0, 15 - half)] = True
            occ[x, 15 + half + 1:] = True
        occ[20, :] = True
        occ[20, 15] = False
        scn = {"map": {"kind": "ascii", "rows": _rows(occ)},
               "start": {"center": [5, 15], "n_robots": 20, "sigma": 2.5, "seed": 0}, "goal": [32, 15]}
        return {"scenario": scn, "interaction": {"k": 7}}, EXP
    if case == "halls50":  # a tour's queue: two halls joined by three 2-cell corridors through an 8-cell wall
        occ = np.zeros((56, 40), dtype=bool)
        occ[24:32, :] = True
        for y0 in (6, 19, 32):
            occ[24:32, y0:y0 + 2] = False
        scn = {"map": {"kind": "ascii", "rows": _rows(occ)},
               "start": {"center": [10, 20], "n_robots": 50, "sigma": 3.5, "seed": 0}, "goal": [46, 20]}
        return {"scenario": scn, "interaction": {"k": 7}}, EXP
    if case == "cross1000":
        scn = {"map": {"kind": "free", "size": [300, 120]},
               "start": {"center": [30, 60], "n_robots": 1000, "sigma": 12.0, "seed": 0}, "goal": [270, 60]}
        return {"scenario": scn, "interaction": {"k": 7}}, EXP
    if case == "cross300":
        scn = {"map": {"kind": "free", "size": [150, 80]},
               "start": {"center": [20, 40], "n_robots": 300, "sigma": 6.5, "seed": 0}, "goal": [130, 40]}
        return {"scenario": scn, "interaction": {"k": 7}}, EXP
    raise SystemExit(f"unknown case {case!r}")


def child(case: str, variant: str, code: str | None, overrides: list[str], arrays: str) -> None:
    """Plan one case with one variant and print its row as JSON (run in a child process); the arrays
    the makespan's lower bound needs go to the file ``arrays``.

    ``plan_s`` times :func:`~mrfswarm.pipeline.plan` alone; ``run_s`` what a user of ``mrfswarm run`` waits for
    after the interpreter starts: importing the package, planning and writing every output (figures, Crazyflie
    files and their certificate) into a scratch folder, the issue's "run time"."""
    started = time.perf_counter()
    use(code)
    import importlib.util

    import numpy as np

    from mrfswarm.config import apply_overrides, from_dict
    from mrfswarm.pipeline import plan

    # the working tree's metrics, whichever code plans
    spec = importlib.util.spec_from_file_location("fq", ROOT / "mrfswarm" / "flight_quality.py")
    fq = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(fq)
    data, base = case_config(case)
    if code:  # keys the baseline does not know (the paper's configs set them to its behaviour, its only one)
        drop_unknown_keys(data)
    data = apply_overrides(data, ["simulation.enabled=false", *VARIANTS[variant], *overrides])
    cfg = from_dict(data, base)
    t0 = time.perf_counter()
    r = plan(cfg, progress=False)
    total = time.perf_counter() - t0
    from mrfswarm.outputs import write_outputs

    with tempfile.TemporaryDirectory() as out:
        write_outputs(r, Path(out) / "run")
    run_total = time.perf_counter() - started
    scn, c = r.scenario, r.continuous
    paths = r.discrete.paths
    d = scn.distances
    # the lower bound is computed by the parent, with the working tree's code (the baseline's goal-field
    # functions differ): the child leaves it what it needs
    np.savez(arrays, free=scn.grid.free, starts=paths[0], ends=paths[-1], resolution=scn.grid.resolution,
             v_max=cfg.smoothing.v_max, **({} if d is None else {"via": d.path}))
    stops = fq.count_stops(c.trajectories)
    moving = np.any(np.diff(paths, axis=0) != 0, axis=2)  # (T, N)
    robots = r.robots()
    row = {"case": case, "variant": variant, "robots": scn.n_robots, "steps": r.discrete.n_steps,
           "makespan_s": round(c.makespan_s, 2),
           "stops": round(stops.mean, 2), "stops_max": int(stops.per_robot.max(initial=0)),
           "speed": round(float(stops.mean_speed.mean()), 2),
           "at_goal": sum(bool(o.at_goal) for o in robots),
           "moving_share": round(float(moving.mean()), 2),
           "plan_s": round(total, 2),
           "run_s": round(run_total, 2),
           "min_sep_m": round(float(c.min_separation), 3)}
    print(json.dumps(row))


def lower_bound(arrays: Path, makespan: float) -> dict:
    """The makespan's lower bound of a child's plan (working tree's :mod:`mrfswarm.flight_quality`)."""
    import numpy as np

    from mrfswarm.flight_quality import makespan_lower_bound

    a = np.load(arrays)
    bound = makespan_lower_bound(a["free"], a["starts"], a["ends"], float(a["resolution"]), float(a["v_max"]),
                                 a["via"] if "via" in a.files else None)
    return {"bound": round(makespan / bound, 2) if bound > 0 else None, "bound_s": round(bound, 2)}


COLUMNS = ["steps", "bound", "stops", "stops_max", "speed", "at_goal", "moving_share", "makespan_s", "bound_s",
           "plan_s", "run_s"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cases", default=DEFAULT_CASES)
    ap.add_argument("--variants", default="default,refined")
    ap.add_argument("--baseline", default="3268301", help="git revision of the previous default ('' for none)")
    ap.add_argument("--baseline-variants", default="default")
    ap.add_argument("--out", type=Path, default=RESULTS / "flight_quality.csv")
    ap.add_argument("--repeat", type=int, default=1, help="rounds of every case, interleaved (median cost ratios)")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="a config override for every run (repeatable)")
    ap.add_argument("--child", nargs=2, metavar=("CASE", "VARIANT"), help=argparse.SUPPRESS)
    ap.add_argument("--code", default=None, help=argparse.SUPPRESS)
    ap.add_argument("--arrays", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        child(*args.child, args.code, args.set, args.arrays)
        return
    rows = []
    print(f"{'case':<10} {'code':<9} {'variant':<8} " + " ".join(f"{c[:12]:>12}" for c in COLUMNS), flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        old = extract(args.baseline, Path(tmp)) if args.baseline else None
        for case in args.cases.split(","):
            runs = [(v, None, "now") for v in args.variants.split(",")]
            if old is not None:
                runs = [(v, old, args.baseline) for v in args.baseline_variants.split(",") if v] + runs
            for round_ in range(args.repeat):
                for v, code, label in runs:
                    arrays = Path(tmp) / "arrays.npz"
                    row = {"code": label, **run_child(Path(__file__), ["--child", case, v, "--arrays", str(arrays),
                                                                       *(f"--set={o}" for o in args.set)], code)}
                    row.update(lower_bound(arrays, row["makespan_s"]))
                    if args.repeat > 1:
                        row["round"] = round_
                    rows.append(row)
                    print(f"{case:<10} {label:<9} {v:<8} " + " ".join(f"{str(row[c]):>12}" for c in COLUMNS),
                          flush=True)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    with open(args.out, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    print(f"bound: makespan / lower bound; stops: per robot; moving_share: robot-steps that move; wrote {args.out}")
    for line in cost_lines(rows):
        print(line)


def cost_lines(rows: list[dict]) -> list[str]:
    """Per case and code, what ``refined`` costs over ``default``: the ratios of their plan_s and run_s, each
    taken within a round (``round``, rows of ``--repeat``) and the median over the rounds; and the rounds whose
    flights differ from the first round's."""
    by: dict[tuple, list[dict]] = {}
    for r in rows:
        by.setdefault((r["case"], r["code"], r["variant"]), []).append(r)
    out = []
    for (case, code, variant), refs in by.items():
        bases = by.get((case, code, "default"))
        for r in refs[1:]:
            if (r.get("makespan_s"), r.get("steps")) != (refs[0].get("makespan_s"), refs[0].get("steps")):
                out.append(f"{case} ({code}) {variant}: round {r.get('round')} flew {r.get('makespan_s')} s in "
                           f"{r.get('steps')} steps, round 0 {refs[0].get('makespan_s')} s in {refs[0].get('steps')}")
        if variant != "refined" or not bases:
            continue
        ratio = {k: _median([ref[k] / base[k] for ref, base in zip(refs, bases) if base.get(k) and ref.get(k)])
                 for k in ("plan_s", "run_s")}
        rounds = f", median of {len(refs)} rounds" if len(refs) > 1 else ""
        out.append(f"refined / default, {case} ({code}{rounds}): " + ", ".join(
            f"{k} {v:.2f} x" if v is not None else f"{k} -" for k, v in ratio.items()))
    return out


def _median(values: list[float]) -> float | None:
    """The median of ``values`` (None for none)."""
    if not values:
        return None
    s = sorted(values)
    mid = len(s) // 2
    return s[mid] if len(s) % 2 else (s[mid - 1] + s[mid]) / 2


if __name__ == "__main__":
    main()
