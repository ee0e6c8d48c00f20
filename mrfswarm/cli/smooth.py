"""``mrfswarm smooth``: waypoints (CSV) -> min-snap trajectory (uav_trajectories CSV).

The job of the uav_trajectories tool, with the closed form or any QP backend. The
trajectory is at rest at both ends; durations are given or derived from a constant
speed. Bad input is a one-line error (exit 2) and nothing is written at ``--out``.
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import solvers.qp
from mrfswarm.config import ScenarioConfig
from mrfswarm.errors import ConfigError
from mrfswarm.trajectory.min_snap import CLOSED_FORM, solve_min_snap
from mrfswarm.trajectory.time_allocation import constant_speed_durations
from mrfswarm.trajectory.uav_csv import DEGREE as CSV_DEGREE
from mrfswarm.trajectory.uav_csv import write_uav_csv
from mrfswarm.trajectory.waypoints import check_waypoints, read_waypoints_csv

DEFAULT_SPEED = 1.0


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("smooth", help="smooth waypoints into a min-snap trajectory (uav_trajectories CSV)",
                       description=__doc__.splitlines()[0])
    p.add_argument("waypoints", metavar="WAYPOINTS.csv", help="CSV with a header line and columns x,y[,z]")
    p.add_argument("--out", required=True, metavar="TRAJ.csv", help="output trajectory (uav_trajectories format)")
    p.add_argument("--durations", metavar="d1,d2,...", help="piece durations in seconds, one per segment")
    p.add_argument("--speed", type=float, metavar="V", help=f"constant speed for the durations (default {DEFAULT_SPEED} m/s)")
    p.add_argument("--qp", default=CLOSED_FORM, metavar="NAME",
                   help="closed_form (default) or a QP backend (see `mrfswarm solvers`)")
    p.add_argument("--degree", type=int, default=CSV_DEGREE, metavar="N", help="polynomial degree (default 7)")
    p.add_argument("--derivative", type=int, default=4, metavar="Q", help="minimized derivative (default 4, snap)")
    p.add_argument("--altitude", type=float, default=None, metavar="Z",
                   help=f"z of a 2-D trajectory (default {ScenarioConfig.altitude} m)")
    p.set_defaults(func=run)


def _durations(text: str) -> list[float]:
    out = []
    for i, tok in enumerate(text.split(",")):
        try:
            d = float(tok)
        except ValueError:
            raise ConfigError(f"--durations: value {i + 1} ({tok.strip()!r}) is not a number") from None
        if not (math.isfinite(d) and d > 0):
            raise ConfigError(f"--durations: value {i + 1} ({tok.strip()}) must be a positive finite number of seconds")
        out.append(d)
    return out


def run(args: argparse.Namespace) -> int:
    q, degree = args.derivative, args.degree
    if q < 1:
        raise ConfigError(f"--derivative must be >= 1, got {q}")
    if degree > CSV_DEGREE:
        raise ConfigError(f"--degree {degree}: the uav_trajectories CSV holds degree <= {CSV_DEGREE}; "
                          "a higher degree cannot be exported without truncating")
    if degree < 2 * q - 1:
        raise ConfigError(f"--degree {degree}: minimizing derivative {q} needs degree >= 2q - 1 = {2 * q - 1}")
    if args.durations is not None and args.speed is not None:
        raise ConfigError("give either --durations or --speed, not both")
    speed = DEFAULT_SPEED if args.speed is None else args.speed
    if not (math.isfinite(speed) and speed > 0):
        raise ConfigError(f"--speed must be a positive finite number, got {args.speed}")
    if args.altitude is not None and not math.isfinite(args.altitude):
        raise ConfigError(f"--altitude must be finite, got {args.altitude}")
    if args.qp != CLOSED_FORM:
        solvers.qp.BACKENDS.get(args.qp)  # unknown or missing backend: SolverNotFound, before any work
    out = Path(args.out)
    if not out.parent.is_dir():
        raise ConfigError(f"--out: directory {str(out.parent)!r} does not exist")
    if out.is_dir():
        raise ConfigError(f"--out: {str(out)!r} is a directory")

    W = read_waypoints_csv(args.waypoints)
    check_waypoints(W, source=args.waypoints)
    if W.shape[1] == 3 and args.altitude is not None:
        raise ConfigError("--altitude applies to 2-D waypoints only; the waypoints have a z column")
    M = W.shape[0] - 1
    if args.durations is not None:
        T = _durations(args.durations)
        if len(T) != M:
            raise ConfigError(f"--durations has {len(T)} value{'s' * (len(T) != 1)}; {M + 1} waypoints need {M}")
    else:
        T = constant_speed_durations(W, speed)

    t0 = time.perf_counter()
    res = solve_min_snap(W, T, degree=degree, derivative=q, backend=args.qp)
    elapsed = time.perf_counter() - t0
    altitude = ScenarioConfig.altitude if args.altitude is None else args.altitude
    write_uav_csv(res.trajectory, out, altitude=altitude)
    print(f"{M} pieces, {res.trajectory.duration:.3f} s, backend {res.backend}, "
          f"solved in {elapsed * 1e3:.2f} ms -> {out}")
    return 0
