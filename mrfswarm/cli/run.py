"""``mrfswarm run CONFIG.toml``: plan a scenario end to end and write its outputs."""

from __future__ import annotations

import argparse
import json
import sys
import warnings
from pathlib import Path

from mrfswarm.cli import _args
from mrfswarm.config import load_config
from mrfswarm.errors import ConfigError, ExportError, PlanWarning
from mrfswarm.run_warnings import flown_warnings as flown_warnings  # importable from here as before


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
        with warnings.catch_warnings():  # said below, after the summary line, in the command's words
            warnings.filterwarnings("ignore", category=PlanWarning)
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
    for text in result.warnings():  # after the summary line, once each (plan()'s PlanWarning of them ignored above)
        print(f"mrfswarm: warning: {text}", file=sys.stderr)
    return 0
