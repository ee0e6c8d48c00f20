"""``mrfswarm figs``: regenerate every figure of the paper (and the animations)."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from mrfswarm.cli import _args


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("figs", help="regenerate the paper's figures (PNG), the animations (GIF) and measured.json")
    p.add_argument("--out", type=_args.output_dir, default=Path("paper_figs"),
                   help="output folder (default: paper_figs)")
    p.add_argument("--quick", action="store_true",
                   help="fewer sweep points and sizes, no animations (a smoke run of every figure)")
    p.add_argument("--only", default=None, metavar="NAME,...",
                   help="comma-separated figure names (an unknown name is refused with the list of them); "
                        "default: all")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from mrfswarm.errors import ConfigError
    from mrfswarm.figures import MEASURED, make_figures, select

    only = None if args.only is None else [s.strip() for s in args.only.split(",") if s.strip()]
    if only == []:  # not "every figure": that is --only left out
        raise ConfigError(f"--only {args.only!r}: no figure named")
    chosen = select(only, args.quick)  # an unknown name fails before anything is computed
    if not chosen:  # only animations named, which --quick leaves out (max() of nothing was a traceback)
        raise ConfigError(f"--only {args.only!r} with --quick: nothing to make (--quick makes no animations)")
    width = max(len(f.name) for f in chosen)

    def report(fig, files, seconds) -> None:
        print(f"{fig.name:{width}s} {seconds:6.1f} s  {', '.join(str(f) for f in files)}", flush=True)

    t0 = time.perf_counter()
    written = make_figures(args.out, quick=args.quick, only=only, on_figure=report)
    n = sum(len(v) for v in written.values())
    print(f"{n} figure files and {MEASURED} in {time.perf_counter() - t0:.1f} s -> {args.out}")
    return 0
