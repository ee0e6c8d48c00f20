"""``mrfswarm run CONFIG.toml``: plan a scenario end to end and write its outputs."""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import solvers.qp
from mrfswarm.cli import _args
from mrfswarm.config import load_config
from mrfswarm.errors import ConfigError, ExportError


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("run", help="plan a scenario and write result.json, paths, trajectories and figures")
    p.add_argument("config", type=Path, help="experiment config (TOML)")
    p.add_argument("--out", type=_args.output_dir, default=None, help="output folder (default: out/<config name>)")
    p.add_argument("--mrf", default=None, metavar="NAME",
                   help="MRF method: shorthand for --set mrf.method=NAME (names: `mrfswarm solvers`)")
    p.add_argument("--qp", default=None, metavar="NAME",
                   help="QP backend of the continuous stage: shorthand for --set smoothing.backend=NAME "
                        "(names: `mrfswarm solvers`)")
    p.add_argument("--nlp", default=None, metavar="NAME",
                   help="NLP backend of the time refinement: shorthand for --set smoothing.nlp=NAME "
                        "--set smoothing.refinement=nlp (names: `mrfswarm solvers`)")
    p.add_argument("--seed", type=_args.seed, default=None,
                   help="seed (integer >= 0) of the start sampling and the MRF method")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a config key by dotted path, e.g. --set interaction.k=7 (repeatable)")
    p.add_argument("--workers", type=_positive_int, default=None,
                   help="processes for the continuous stage's chunks of robots and the simulation "
                        "(default: the machine's cores; plans do not depend on it)")
    p.add_argument("--animate", action="store_true", help="also write an animation (GIF) of the swarm")
    p.add_argument("--overwrite", action="store_true",
                   help="replace the run already in --out as a whole (a folder without result.json is never replaced)")
    p.set_defaults(func=run)


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be a whole number >= 1, got {text!r}")
    return value


def flown_warnings(flown: dict | None, radius: float) -> list[str]:
    """What a run's simulated flight (``result.json``'s ``simulation``) warns of: a flight that came closer than the
    plan (the plan is certified; the simulated tracking is not part of the proof, docs/guarantees.md), and a tracking
    bound past the robot radius, which guarantees no flown clearance or separation at all (negative guarantees)."""
    if flown is None:
        return []
    out = []
    safety = 2 * radius
    bound = flown["tracking_error_bound_m"]
    clearance = flown.get("min_obstacle_clearance_m")
    grazed = clearance is not None and clearance < radius and not flown["entered_obstacle"]
    if flown["min_separation_m"] < safety or flown["entered_obstacle"] or grazed:
        parts = []
        if flown["min_separation_m"] < safety:  # 2 r: the two bodies overlap
            parts.append(f"two robots {flown['min_separation_m']:.3f} m apart, less than twice the radius "
                         f"({safety:g} m): their bodies touch")
        if flown["entered_obstacle"]:
            parts.append("a robot inside an obstacle")
        elif grazed:  # a tour's arena flew 0.096 m from a wall at radius 0.1 without a word
            parts.append(f"a robot {clearance:.3f} m from an obstacle, less than its radius ({radius:g} m)")
        guarantee = ""
        if bound is not None:
            sep = flown["guaranteed_separation_m"]
            guarantee = f" (bound {bound * 100:.1f} cm, " + (f"flown separation guaranteed {sep:.3f} m)" if sep >= 0
                                                              else "no flown separation guaranteed)")
        out.append(f"the simulated flight came closer than the plan: {' and '.join(parts)}; tracking error "
                   f"{flown['max_tracking_error_m'] * 100:.1f} cm{guarantee}: see result.json's simulation")
    if bound is not None and (flown.get("guaranteed_clearance_m") or 0.0) < 0:
        out.append(f"the tracking bound of this flight ({bound * 100:.1f} cm) exceeds the robot radius ({radius:g} m): "
                   f"the simulation guarantees no flown clearance ({flown['guaranteed_clearance_m']:.3f} m) or "
                   f"separation ({flown['guaranteed_separation_m']:.3f} m), only what it measured (error "
                   f"{flown['max_tracking_error_m'] * 100:.1f} cm); a lower smoothing.j_max or v_max lowers the bound "
                   "(docs/guarantees.md)")
    return out


#: Why a robot (``result.json``'s ``robots[].stop_reason``) did not reach the goal, as the run's last line says it.
WHY_SHORT = {
    "trapped": "trapped (the goal field leads them to a local minimum short of the goal, or they queue behind one)",
    "stalled": "stalled (held where they are by the robots around them)",
    "unreachable": "unreachable (no free path to the goal)",
    "max_steps": "on their way at mrf.max_steps",
}


def short_of_goal(robots: list[dict], distance: str) -> str | None:
    """The run's last line when robots did not reach the goal for another reason than the step budget (whose line
    says which key to raise): how many, and why. A crowd behind a one-cell door under the paper's rules ended with
    0 of 20 at the goal, said only inside the summary line's parentheses, and exit code 0 as any plan written."""
    why: dict[str, int] = {}
    for r in robots:
        if r["stop_reason"] is not None:
            why[r["stop_reason"]] = why.get(r["stop_reason"], 0) + 1
    if set(why) <= {"max_steps"}:
        return None
    short = sum(why.values())
    line = (f"{short} of {len(robots)} robot{'s' * (len(robots) > 1)} did not reach the goal: "
            + ", ".join(f"{why[k]} {WHY_SHORT.get(k, k)}" for k in [*(k for k in WHY_SHORT if k in why),
                                                                      *(k for k in why if k not in WHY_SHORT)]))
    if "trapped" in why and distance == "euclidean":
        line += '; goal_potential.distance = "geodesic" (the default) leads around walls'
    return line + "; the plan is written as any other (see result.json's robots)"


#: A failed run given --overwrite over a complete run is written to ``DIR`` + this, the complete run kept.
FAILED_SUFFIX = ".failed"


def _complete_run(out: Path) -> bool:
    """Whether ``out`` holds a run that completed (its ``result.json`` says so, with no failure)."""
    try:
        summary = json.loads((Path(out) / "result.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False
    return isinstance(summary, dict) and summary.get("complete") is True and summary.get("failure") is None


def run(args: argparse.Namespace) -> int:
    from mrfswarm.errors import PlanError
    from mrfswarm.outputs import check_output_dir, write_outputs
    from mrfswarm.pipeline import plan

    cfg = load_config(args.config, args.overrides)
    out = args.out
    if out is None:
        try:
            out = _args.output_dir(str(Path("out") / args.config.stem))
        except argparse.ArgumentTypeError as e:
            raise ConfigError(f"default output folder {e}; give --out") from None
    check_output_dir(out, args.overwrite)  # before planning, not after
    try:
        result = plan(cfg, mrf=args.mrf, qp=args.qp, nlp=args.nlp, seed=args.seed, workers=args.workers)
    except PlanError as e:  # keep what was computed before the failure
        where = out
        if args.overwrite and _complete_run(out):
            # a failed run does not replace a complete one (a tour's --overwrite lost a good run so): it goes beside
            where = out.with_name(out.name + FAILED_SUFFIX)
            try:
                check_output_dir(where, overwrite=True)
            except ExportError as refused:
                raise PlanError(f"{e} (the run in {out} is kept; what was computed is not written: {refused})",
                                e.result) from e
        write_outputs(e.result, where, overwrite=args.overwrite or where != out)
        kept = f"; the run in {out} is kept" if where != out else ""
        raise PlanError(f"{e} (what was computed is in {where}{kept})", e.result) from e
    write_outputs(result, out, animate=args.animate, overwrite=args.overwrite)
    s = result.summary()
    goal = "" if s["reached_goal"] is None else (
        f", reached goal: {s['reached_goal']}, robots at goal: {s['robots_at_goal']}/{s['n_robots']}")
    short = [r for r in s["robots"] if r["stop_reason"] is not None]
    if short:
        why: dict[str, list[str]] = {}
        for r in short:
            why.setdefault(r["stop_reason"], []).append(str(r["robot"]))
        goal += " (" + "; ".join(f"{k}: robot{'s' * (len(v) > 1)} {', '.join(v[:8])}{' ...' if len(v) > 8 else ''}"
                                 for k, v in why.items()) + ")"
    if s["robots_separated"]:
        goal += f", {s['robots_separated']} separated from the swarm"
    # the map says whether the run is 3-D, not the goal: a formation flight has none
    scaled = s["downwash"] != 1 and result.scenario.grid.ndim == 3
    line = (f"{s['n_robots']} robots, {s['mrf_steps']} MRF steps ({s['mrf']}, {s['stop_reason']}{goal}), "
            f"min separation{' (downwash-scaled)' if scaled else ''} "
            f"{s['min_separation_discrete']:.2f} m discrete")
    if s["min_separation_continuous"] is not None:
        # the NLP backend too where one refined the durations (a solver tour saw only the QP's named)
        line += (f", {s['min_separation_continuous']:.2f} m smooth ({result.smoothing_solvers}), makespan "
                 f"{s['makespan_s']:.1f} s")
        q = s["flight_quality"]
        if q["makespan_over_bound"] is not None:
            line += f" ({q['makespan_over_bound']:.2f} x the lower bound, {q['stops_per_robot']:.2f} stops per robot)"
    if s["simulation"] is not None:
        line += f", flown: max tracking error {s['simulation']['max_tracking_error_m'] * 100:.1f} cm"
    print(f"{line} -> {out}")
    over = [r for r in s["robots"] if r["stop_reason"] == "max_steps"]
    if over:  # a long way: the plan ends where the step budget does, not at the goal (a tour's city map, 0 of 30)
        left = max(r["goal_distance_m"] for r in over)
        more = math.ceil(left / result.scenario.grid.resolution)  # a cell a step (a diagonal step goes 1.4)
        print(f"mrfswarm: warning: the discrete plan ended at mrf.max_steps = {cfg.mrf.max_steps} with {len(over)} "
              f"robot{'s' * (len(over) > 1)} on the way to the goal, the farthest {left:.1f} m from it (about "
              f"{more} more steps at a cell a step): raise it, e.g. --set mrf.max_steps="
              f"{100 * math.ceil((cfg.mrf.max_steps + more) / 100)}", file=sys.stderr)
    crazyflie = s.get("crazyflie") or {}
    if crazyflie.get("advice"):  # a long flight fits no format: said here, not first by the scripts at the radio
        print(f"mrfswarm: warning: {crazyflie['advice']}", file=sys.stderr)
    for text in flown_warnings(s["simulation"], cfg.scenario.robot_radius):
        print(f"mrfswarm: warning: {text}", file=sys.stderr)
    witness = (s.get("window_attempts") or {}).get("witness", 0)
    if witness:  # safe, but slow: a window where every planned duration failed flies from rest to rest
        reasons = s.get("witness_reasons") or []
        because = f" (last rejected: {reasons[0]}{f'; {len(reasons) - 1} other reasons' if len(reasons) > 1 else ''})" \
            if reasons else ""
        print(f"mrfswarm: warning: {witness} of {s['windows']} smoothing windows had no solution at their planned "
              f"durations and fly the rest-to-rest witness (slower, with stops){because}: see result.json's "
              "witness_reasons; smoothing.qp_options or the QP backend may be too tight", file=sys.stderr)
    failures = s.get("solve_failures") or {"windows": 0}
    # a backend with an iteration cap (piqp, proxsuite) fails the faster attempts that do not converge within it by
    # design (clutter40: 8 of 16 windows); one without fails where it solves inaccurately (SCS: 3 of 9 on the corridor)
    if failures["windows"] and 4 * failures["windows"] >= s["windows"] and \
            solvers.qp.BACKENDS.get(s["qp"]).capabilities.iteration_cap is None:
        status = f" (status {failures['statuses'][0]!r})" if failures["statuses"] else ""
        print(f"mrfswarm: warning: the QP backend {s['qp']} did not solve attempts of {failures['windows']} of "
              f"{s['windows']} smoothing windows{status}: they fly slower attempts; see result.json's solve_failures",
              file=sys.stderr)
    errors = s.get("refinement_errors") or []
    if errors:  # the refinement only shortens a certified flight: a backend that raised leaves the window as it was
        more = f" ({len(errors) - 1} other errors in result.json's refinement_errors)" if len(errors) > 1 else ""
        print(f"mrfswarm: warning: the time refinement's NLP backend raised: {errors[0]}{more}; those windows fly "
              "their QP's durations or the best point it had evaluated", file=sys.stderr)
    home = short_of_goal(s["robots"], result.config.goal_potential.distance)
    if home:  # last: what a user reads first of a run that did not bring the swarm home
        print(f"mrfswarm: warning: {home}", file=sys.stderr)
    return 0
