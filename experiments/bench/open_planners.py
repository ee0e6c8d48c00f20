"""Our planner against an open multi-robot planner on the flight-quality maps, the same continuous stage after both.

The open planner is libMultiRobotPlanning (W. Hönig, https://github.com/whoenig/libMultiRobotPlanning): its
Conflict-Based Search with optimal task assignment, ``ecbs_ta`` (bounded suboptimal, ``--w``) or ``cbs_ta``
(optimal), the discrete stage of the safe-corridor swarm planners (Hönig et al., "Trajectory planning for
quadrotor swarms", 2018). Its task assignment suits one swarm goal: every robot may end in any of the goal
cells. It is handed the cells our swarm ended in, so both plans end on the same cells, whichever robot takes
which, and it minimizes the sum of its robots' moves on the 4-connected grid.

Both discrete plans are then smoothed by this package's continuous stage (the case's smoothing settings,
flight simulation off) and scored alike: the makespan over the assignment-free bound
(:func:`mrfswarm.flight_quality.assignment_free_bound`: the longest shortest free path, minimized over which
robot takes which final cell, at v_max), stops per robot, planning time (discrete and continuous), and the
steps where the discrete plan breaks our discrete safety invariants (two robots moving at once closer than a
cell apart, a straight move closer than half a cell to an obstacle: :func:`mrfswarm.discrete.safety.discrete_violations`).
The continuous stage certifies its own trajectories whatever the discrete plan; it may refuse one that breaks
them.

Build the open planner first (Debian: ``apt-get install cmake g++ libboost-program-options-dev libyaml-cpp-dev``)::

    git clone https://github.com/whoenig/libMultiRobotPlanning && cd libMultiRobotPlanning
    mkdir build && cd build && cmake .. -DCMAKE_BUILD_TYPE=Release && make ecbs_ta cbs_ta

then::

    python experiments/bench/open_planners.py --lmrp libMultiRobotPlanning/build [--cases ...]
        [--planners ecbs_ta,cbs_ta] [--w 1.3] [--timeout 300] [--out experiments/bench/results/open_planners.csv]

Cases are those of ``flight_quality.py`` on 2-D maps (the open planner's grids are planar).
"""

from __future__ import annotations

import argparse
import csv
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parent))
from flight_quality import case_config  # noqa: E402

from mrfswarm import flight_quality as fq  # noqa: E402
from mrfswarm.config import apply_overrides, from_dict  # noqa: E402
from mrfswarm.discrete.safety import discrete_violations  # noqa: E402
from mrfswarm.pipeline import build_scenario, plan  # noqa: E402

DEFAULT_CASES = "corridor,doorway,forest,rooms,trap,arena8,aisles30,clutter40,open50"
FIELDS = ["case", "planner", "robots", "steps", "moves", "discrete_s", "continuous_s", "plan_s", "makespan_s",
          "bound_s", "over_bound", "stops", "at_goal", "unsafe_steps", "status"]


def problem_yaml(free: np.ndarray, starts: np.ndarray, goals: np.ndarray) -> dict:
    """The open planner's input: the map, and every robot's start with every goal cell as a potential goal."""
    obstacles = np.argwhere(~free)
    return {"map": {"dimensions": [int(free.shape[0]), int(free.shape[1])],
                    "obstacles": [[int(x), int(y)] for x, y in obstacles]},
            "agents": [{"name": f"agent{i}", "start": [int(s[0]), int(s[1])],
                        "potentialGoals": [[int(g[0]), int(g[1])] for g in goals]} for i, s in enumerate(starts)]}


def schedule_paths(schedule: dict, n: int) -> np.ndarray:
    """(T + 1, N, 2) cells from the open planner's output schedule: each agent's states one per time step, in order
    (their ``t`` is the cost so far, which stands still while an agent waits on a goal cell, free there, before it
    moves on: it is not the time); an agent stays at its last cell once it has arrived."""
    states = [schedule[f"agent{i}"] for i in range(n)]
    T = max(len(st) for st in states) - 1
    paths = np.zeros((T + 1, n, 2), dtype=np.int64)
    for i, st in enumerate(states):
        for k, s in enumerate(st):
            paths[k:, i] = (s["x"], s["y"])
    return paths


def unsafe_steps(paths: np.ndarray, free: np.ndarray, downwash: float) -> int:
    """Steps of ``paths`` that break our discrete invariants (one step counts once, whatever it breaks)."""
    return len({m.partition(":")[0] for m in discrete_violations(paths, free, limit=10**9, downwash=downwash)})


def run_open_planner(binary: Path, free: np.ndarray, starts: np.ndarray, goals: np.ndarray, w: float,
                     timeout: float) -> tuple[np.ndarray | None, float, str]:
    """The open planner's paths (None if it found none), its own planning time (s), and a status."""
    with tempfile.TemporaryDirectory() as tmp:
        src, out = Path(tmp) / "in.yaml", Path(tmp) / "out.yaml"
        src.write_text(yaml.safe_dump(problem_yaml(free, starts, goals)))
        cmd = [str(binary.resolve()), "-i", str(src), "-o", str(out)] + (["-w", str(w)] if binary.name.startswith("e") else [])
        t0 = time.perf_counter()
        try:
            proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, cwd=tmp)  # it writes files there
        except subprocess.TimeoutExpired:
            return None, time.perf_counter() - t0, f"timeout {timeout:g} s"
        wall = time.perf_counter() - t0
        if not out.exists():
            return None, wall, (proc.stdout.strip() or proc.stderr.strip() or f"exit {proc.returncode}")[:60]
        result = yaml.safe_load(out.read_text())
        return schedule_paths(result["schedule"], len(starts)), float(result["statistics"]["runtime"]), "ok"


def smooth(paths: np.ndarray, cfg, scn):
    """The continuous stage on ``paths`` with the case's settings: (plan or None, seconds, status)."""
    from mrfswarm.continuous import RecedingHorizon
    from mrfswarm.pipeline import qp_options

    t0 = time.perf_counter()
    try:
        rh = RecedingHorizon(paths, scn.grid, cfg.smoothing, cfg.scenario.robot_radius, cfg.smoothing.backend,
                             qp_options(cfg), workers=1, downwash=cfg.scenario.downwash)
        out = rh.run()
    except Exception as e:  # the continuous stage refusing a plan is a result here
        return None, time.perf_counter() - t0, f"{type(e).__name__}: {str(e)[:80]}"
    return out, time.perf_counter() - t0, "ok" if out.certificate.ok else "not certified"


def row(case: str, planner: str, paths: np.ndarray, discrete_s: float, cfg, scn, bound: float, goals: set) -> dict:
    moved = np.any(np.diff(paths, axis=0) != 0, axis=-1)
    out, cont_s, status = smooth(paths, cfg, scn)
    r = {"case": case, "planner": planner, "robots": paths.shape[1], "steps": len(paths) - 1,
         "moves": int(moved.sum()), "discrete_s": round(discrete_s, 3), "continuous_s": round(cont_s, 3),
         "plan_s": round(discrete_s + cont_s, 3), "bound_s": round(bound, 3),
         "at_goal": sum(tuple(c) in goals for c in paths[-1].tolist()),
         "unsafe_steps": unsafe_steps(paths, scn.grid.free, cfg.scenario.downwash), "status": status}
    if out is not None:
        r["makespan_s"] = round(out.makespan_s, 3)
        r["over_bound"] = round(out.makespan_s / bound, 3) if bound > 0 else None
        r["stops"] = round(fq.count_stops(out.trajectories).mean, 3)
    return r


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--lmrp", type=Path, required=True, help="libMultiRobotPlanning's build folder (its binaries)")
    ap.add_argument("--cases", default=DEFAULT_CASES)
    ap.add_argument("--planners", default="ecbs_ta", help="open planners, of ecbs_ta, cbs_ta (default ecbs_ta)")
    ap.add_argument("--w", type=float, default=1.3, help="ecbs_ta's suboptimality bound (default 1.3)")
    ap.add_argument("--variants", default="default", help="our smoothing settings, of default, refined "
                    "(smoothing.time_refinement); both plans get them (default: default)")
    ap.add_argument("--timeout", type=float, default=300.0, help="seconds the open planner gets per case")
    ap.add_argument("--out", type=Path, default=None, help="CSV of the rows")
    args = ap.parse_args(argv)
    planners = [p for p in args.planners.split(",") if p]
    for p in planners:
        if p not in ("ecbs_ta", "cbs_ta"):
            ap.error(f"--planners: unknown planner {p!r} (ecbs_ta, cbs_ta)")
        if not (args.lmrp / p).is_file():
            ap.error(f"--lmrp: no {p} binary in {str(args.lmrp)!r} (build it as the help says)")
    variants = {"default": [], "refined": ["smoothing.time_refinement=true"]}
    chosen = [v for v in args.variants.split(",") if v]
    for v in chosen:
        if v not in variants:
            ap.error(f"--variants: unknown variant {v!r} (default, refined)")
    if not args.w >= 1:
        ap.error(f"--w: {args.w:g}, the suboptimality bound must be >= 1")
    if not args.timeout > 0:
        ap.error(f"--timeout: {args.timeout:g}, must be > 0")
    configs = {case: case_config(case) for case in [c for c in args.cases.split(",") if c]}  # bad names first
    rows = []
    for case, (data, base) in configs.items():
        cfgs = {v: from_dict(apply_overrides(data, ["simulation.enabled=false", *variants[v]]), base) for v in chosen}
        scn = build_scenario(cfgs[chosen[0]])
        if scn.grid.ndim != 2:
            print(f"{case}: skipped (a voxel map; the open planner's grids are planar)", flush=True)
            continue
        theirs: dict[str, tuple] = {}
        for v, cfg in cfgs.items():
            t0 = time.perf_counter()
            ours = plan(cfg, progress=False, workers=1)
            ours_s = time.perf_counter() - t0
            paths = ours.discrete.paths  # the same discrete plan for every variant
            starts, goals = paths[0], paths[-1]
            bound = fq.assignment_free_bound(scn.grid.free, starts, goals, scn.grid.resolution, cfg.smoothing.v_max)
            # the final cells in the goal region: a robot of either plan that ends on one is at the goal
            goal_set = {tuple(c) for c, o in zip(goals.tolist(), ours.robots()) if o.at_goal}
            tag = "" if v == "default" else f", {v}"
            r = {"case": case, "planner": f"mrfswarm ({cfg.mrf.method}{tag})", "robots": paths.shape[1],
                 "steps": len(paths) - 1, "moves": int(np.any(np.diff(paths, axis=0) != 0, axis=-1).sum()),
                 "discrete_s": round(ours.timings_s["discrete"], 3), "plan_s": round(ours_s, 3),
                 "continuous_s": round(ours_s - ours.timings_s["discrete"], 3),
                 "makespan_s": round(ours.continuous.makespan_s, 3), "bound_s": round(bound, 3),
                 "over_bound": round(ours.continuous.makespan_s / bound, 3),
                 "stops": round(ours.flight_quality()["stops_per_robot"], 3), "at_goal": sum(bool(o.at_goal) for o in ours.robots()),
                 "unsafe_steps": unsafe_steps(paths, scn.grid.free, cfg.scenario.downwash),
                 "status": "ok" if ours.continuous.certificate.ok else "not certified"}
            rows.append(r)
            print(_line(r), flush=True)
            for p in planners:
                if p not in theirs:
                    theirs[p] = run_open_planner(args.lmrp / p, scn.grid.free, starts, goals, args.w, args.timeout)
                their_paths, their_s, status = theirs[p]
                name = (f"{p} (w {args.w:g})" if p == "ecbs_ta" else p) + tag
                if their_paths is None:
                    r = {"case": case, "planner": name, "robots": len(starts), "discrete_s": round(their_s, 3),
                         "status": status}
                else:
                    r = row(case, name, their_paths, their_s, cfg, scn, bound, goal_set)
                rows.append(r)
                print(_line(r), flush=True)
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        with open(args.out, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=FIELDS)
            w.writeheader()
            w.writerows(rows)
    return 0


def _line(r: dict) -> str:
    def g(k: str) -> str:
        return str(r[k]) if r.get(k) is not None else "-"
    return (f"{r['case']:<10} {r['planner']:<20} steps {g('steps'):>4}  moves {g('moves'):>5}  "
            f"makespan {g('makespan_s'):>7} s = {g('over_bound'):>6} x bound  stops {g('stops'):>5}  "
            f"plan {g('plan_s'):>7} s (discrete {g('discrete_s'):>7})  unsafe steps {g('unsafe_steps'):>3}  {r['status']}")


if __name__ == "__main__":
    sys.exit(main())
