"""``mrfswarm sweep CONFIG.toml --grid KEY=V1,V2 ... --out DIR``: a parameter study, one table."""

from __future__ import annotations

import argparse
from pathlib import Path

from mrfswarm.cli import _args


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("sweep", help="plan every point of a parameter grid; one result.json per point, one CSV table",
                       description="Plan every point of the Cartesian product of the --grid values (row-major, in "
                                   "the order given), in local processes or on a Dask cluster; write "
                                   "DIR/points/<i>_<slug>/result.json, DIR/sweep.csv and DIR/sweep.json.")
    p.add_argument("config", type=Path, help="experiment config (TOML)")
    p.add_argument("--grid", action="append", default=[], required=True, metavar="KEY=V1,V2,...",
                   help="a config key and its values, TOML literals as for --set, e.g. "
                        "--grid interaction.k_a=8,14,20 (repeatable: the points are the product)")
    p.add_argument("--out", type=_args.output_dir, required=True, help="output folder")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help='run on this Dask distributed scheduler, e.g. tcp://host:8786 (pip install "mrfswarm[dask]")')
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help="local processes (default: the number of CPUs; 1 runs in this process)")
    p.add_argument("--seeds", default=None, metavar="S1,S2,...",
                   help="plan each point once per seed (start sampling and optimizer), e.g. 0,1,2")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a config key for every point (repeatable)")
    p.add_argument("--figures", action="store_true", help="also write each point's figures and paths")
    p.add_argument("--overwrite", action="store_true",
                   help="replace the sweep the output folder holds (deleted once this one completes)")
    p.add_argument("--connect-timeout", type=_args.positive_float, default=10.0, metavar="S",
                   help="seconds to wait for the Dask scheduler (default 10)")
    p.set_defaults(func=run)


def parse_seeds(text: str) -> list[int]:
    """``"0,1,2"`` -> ``[0, 1, 2]``; raises :class:`ConfigError` naming a bad item."""
    from mrfswarm.errors import ConfigError

    seeds = []
    for item in text.split(","):
        try:
            seeds.append(int(item.strip()))
        except ValueError:
            raise ConfigError(f"--seeds {text!r}: {item.strip()!r} is not an integer") from None
        if seeds[-1] < 0:
            raise ConfigError(f"--seeds {text!r}: {item.strip()!r} must be an integer >= 0")
    return seeds


def run(args: argparse.Namespace) -> int:
    from mrfswarm.sweep import parse_grid, run_sweep

    grid = parse_grid(args.grid)
    seeds = None if args.seeds is None else parse_seeds(args.seeds)
    res = run_sweep(args.config, grid, args.out, scheduler=args.scheduler, workers=args.workers, seeds=seeds,
                    overrides=args.overrides, figures=args.figures, connect_timeout=args.connect_timeout,
                    overwrite=args.overwrite)
    failed = len(res.failed)
    print(f"{len(res.rows)} runs ({failed} failed) -> {res.csv_path}")
    return 0
