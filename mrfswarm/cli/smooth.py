"""``mrfswarm smooth``: waypoints (CSV) -> min-snap trajectory (uav_trajectories CSV).

The job of the uav_trajectories tool, with the closed form or any QP backend. The
trajectory is at rest at both ends; durations are given (``--durations``) or derived
from a constant speed (``--speed``). Time can then be optimized:

- ``--v-max``, ``--a-max``: limits on the speed and acceleration norms that the output
  meets, by its exact maxima (not samples). Alone, they slow the trajectory down
  uniformly if it exceeds one (never speed it up).
- ``--refine-time``: the durations are refined by minimizing snap + ``k_T`` x total
  time (Richter et al.; exact duration gradient of the closed form, L-BFGS-B; see
  :mod:`mrfswarm.trajectory.time_allocation`). The weight only sets the time scale: the
  optimal shares of the pieces do not depend on it. So without ``--time-weight``,
  refinement keeps the total duration and redistributes it, and with limits it gives
  the fastest refined trajectory within them (uniform scaling until a limit is tight,
  which is the optimum for the largest weight that meets both). With ``--time-weight``
  the total follows from the weight, and limits only ever slow it down.
- ``--retime toppra`` (needs ``--v-max`` and ``--a-max``, and the ``toppra`` extra):
  toppra's time-optimal traversal of the trajectory's path under the limits, refit as
  a degree-``2q - 1`` min-snap trajectory through points of the path (10 pieces per
  input piece) and scaled to meet the limits exactly, or, if that refit is slower, the
  input scaled uniformly until a limit is tight (see
  :mod:`mrfswarm.trajectory.retiming`); with ``--refine-time`` the path is that of the
  refined durations. This is the shortest flight of the options: refinement trades
  snap against time and does not see the limits.

Bad input is a one-line error (exit 2) and nothing is written at ``--out``: every
value is checked before any work, and the file is written last, atomically. An existing
``--out`` is refused unless ``--overwrite`` is given.
"""

from __future__ import annotations

import argparse
import logging
import math
import sys
import time
from pathlib import Path

import numpy as np

import solvers.qp
from mrfswarm.atomic import not_writable
from mrfswarm.config import ScenarioConfig
from mrfswarm.errors import ConfigError, SolverNotFound
from mrfswarm.trajectory.min_snap import CLOSED_FORM, solve_min_snap
from mrfswarm.trajectory.problem import DEFAULT_DEGREE, DEFAULT_DERIVATIVE
from mrfswarm.trajectory.retiming import require_toppra, retime_toppra, scale_to_limits
from mrfswarm.trajectory.time_allocation import constant_speed_durations, refine_durations, scaled_time_weight
from mrfswarm.trajectory.uav_csv import DEGREE as CSV_DEGREE
from mrfswarm.trajectory.uav_csv import write_uav_csv
from mrfswarm.trajectory.waypoints import check_waypoints, read_waypoints_csv

DEFAULT_SPEED = 1.0
RETIMERS = ("toppra",)
#: Piece durations (s) the solvers take: shorter pieces are not flown (a Crazyflie evaluates its trajectory at
#: 100-500 Hz), and beyond either end the powers of the durations overflow or the solution loses the waypoints.
MIN_PIECE_S, MAX_PIECE_S = 1e-3, 1e5
#: How far (m) the solved trajectory may pass from a waypoint (PIQP's default tolerance gives 1e-9 m; durations
#: 1e-4 : 1 left it 4 mm off, 1e-6 : 1 with the closed form 1 m off); at least WAYPOINT_REL of the waypoints'
#: largest coordinate, whose float rounding grows with it (waypoints 200 km from the origin).
WAYPOINT_TOL = 1e-5
WAYPOINT_REL = 1e-9
#: Pieces a Crazyflie's 4096-byte trajectory memory holds in the raw format (132 bytes a piece).
CRAZYFLIE_PIECES = 31


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("smooth", help="smooth waypoints into a min-snap trajectory (uav_trajectories CSV)",
                       description="Waypoints (CSV) -> min-snap trajectory (uav_trajectories CSV).")
    p.add_argument("waypoints", metavar="WAYPOINTS.csv", help="CSV with a header line and columns x,y[,z]")
    p.add_argument("--out", required=True, metavar="TRAJ.csv", help="output trajectory (uav_trajectories format)")
    p.add_argument("--overwrite", action="store_true", help="replace --out if it exists (refused otherwise)")
    p.add_argument("--durations", metavar="d1,d2,...", help="piece durations in seconds, one per segment")
    p.add_argument("--speed", type=float, metavar="V", help=f"constant speed for the durations (default {DEFAULT_SPEED} m/s)")
    p.add_argument("--qp", default=CLOSED_FORM, metavar="NAME",
                   help="closed_form (default; the banded closed form where it applies) or another QP backend "
                        "(see `mrfswarm solvers`)")
    p.add_argument("--degree", type=int, default=DEFAULT_DEGREE, metavar="N",
                   help=f"polynomial degree (default {DEFAULT_DEGREE})")
    p.add_argument("--derivative", type=int, default=DEFAULT_DERIVATIVE, metavar="Q",
                   help=f"minimized derivative (default {DEFAULT_DERIVATIVE}, snap)")
    p.add_argument("--altitude", type=float, default=None, metavar="Z",
                   help=f"z of a 2-D trajectory (default {ScenarioConfig.altitude} m)")
    p.add_argument("--v-max", type=float, default=None, metavar="V", help="speed limit the output meets (m/s)")
    p.add_argument("--a-max", type=float, default=None, metavar="A", help="acceleration limit the output meets (m/s^2)")
    p.add_argument("--refine-time", action="store_true",
                   help="refine the durations (snap + time weight x total time), then meet the limits")
    p.add_argument("--time-weight", type=float, default=None, metavar="K",
                   help="with --refine-time: price of one second in cost units (default: keep the total "
                        "duration, or with limits the fastest refined trajectory within them)")
    p.add_argument("--retime", choices=RETIMERS, default=None,
                   help="retime to the limits with toppra (needs --v-max, --a-max and the toppra extra)")
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


def _check_piece_durations(T: np.ndarray, source: str) -> None:
    """Every piece between :data:`MIN_PIECE_S` and :data:`MAX_PIECE_S` (``source`` names what gave them)."""
    for bad, bound, side in ((T < MIN_PIECE_S, MIN_PIECE_S, "shorter"), (T > MAX_PIECE_S, MAX_PIECE_S, "longer")):
        if bad.any():
            i = int(np.argmax(bad))
            raise ConfigError(f"{source} gives piece {i + 1} a duration of {T[i]:.3g} s, {side} than {bound:g} s "
                              "(pieces are solved and flown between 1 ms and 1e5 s)")


def _check_passes_waypoints(traj, W: np.ndarray, T: np.ndarray) -> None:
    """The solved trajectory passes every waypoint within :data:`WAYPOINT_TOL` (very uneven durations lose them:
    the solution is written only if it is the trajectory asked for)."""
    c = np.asarray(traj.coefficients, dtype=float)  # (M, D + 1, dim), local time
    durations = np.asarray(traj.durations, dtype=float)
    with np.errstate(all="ignore"):
        ends = np.einsum("mkd,mk->md", c, durations[:, None] ** np.arange(c.shape[1]))
    # waypoint j against the pieces that meet there: the start of piece j and the end of piece j - 1
    miss = np.zeros(len(W))
    miss[:-1] = np.linalg.norm(c[:, 0, :] - W[:-1], axis=1)
    miss[1:] = np.maximum(miss[1:], np.linalg.norm(ends - W[1:], axis=1))
    miss[~np.isfinite(miss)] = np.inf
    if not np.all(miss <= max(WAYPOINT_TOL, WAYPOINT_REL * float(np.abs(W).max()))):
        i = int(np.argmax(miss))
        raise ConfigError(f"the solved trajectory misses waypoint {i + 1} by {miss[i]:.3g} m: the durations are too "
                          f"uneven for the solver (shortest {T.min():.3g} s, longest {T.max():.3g} s); give more even "
                          "--durations")


def _positive(flag: str, value: float | None, unit: str) -> None:
    if value is not None and not (math.isfinite(value) and value > 0):
        raise ConfigError(f"{flag} must be a positive finite number ({unit}), got {value}")


def _check_time_options(args: argparse.Namespace, degree: int, q: int) -> None:
    """Every time-optimization flag and combination, before any work."""
    _positive("--v-max", args.v_max, "m/s")
    _positive("--a-max", args.a_max, "m/s^2")
    _positive("--time-weight", args.time_weight, "cost units per second")
    if args.time_weight is not None and not args.refine_time:
        raise ConfigError("--time-weight is the weight of --refine-time; add --refine-time or drop --time-weight")
    if args.retime is not None:
        if args.v_max is None or args.a_max is None:
            missing = " and ".join(f for f, v in (("--v-max", args.v_max), ("--a-max", args.a_max)) if v is None)
            raise ConfigError(f"--retime {args.retime} retimes to the limits: give {missing}")
        if args.time_weight is not None:
            raise ConfigError(f"--time-weight has no effect with --retime {args.retime}, which sets the time law "
                              "(the refined path does not depend on the weight); drop --time-weight")
    if args.refine_time and degree != 2 * q - 1:
        raise ConfigError(f"--refine-time needs --degree 2q - 1 = {2 * q - 1} (the closed form's duration gradient), "
                          f"got --degree {degree}")
    if args.retime is not None and degree != 2 * q - 1:
        raise ConfigError(f"--retime {args.retime} refits with degree 2q - 1 = {2 * q - 1}; give --degree {2 * q - 1}, "
                          f"got --degree {degree}")
    if args.retime == "toppra":
        require_toppra()


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
    if args.altitude is not None and not (math.isfinite(args.altitude) and args.altitude > 0):
        raise ConfigError(f"--altitude must be a finite number > 0 (as scenario.altitude), got {args.altitude}")
    _check_time_options(args, degree, q)
    if args.qp != CLOSED_FORM:
        try:  # unknown or missing backend: SolverNotFound, before any work
            solvers.qp.BACKENDS.get(args.qp)
        except SolverNotFound as e:
            raise SolverNotFound(f"--qp: {e}") from e
    out = Path(args.out)
    if not out.parent.is_dir():
        raise ConfigError(f"--out: directory {str(out.parent)!r} does not exist")
    if out.is_dir():
        raise ConfigError(f"--out: {str(out)!r} is a directory")
    why = not_writable(out.parent)
    if why is not None:
        raise ConfigError(f"--out: {str(out)!r} cannot be written: {why}")
    if out.exists() and Path(args.waypoints).exists() and out.samefile(args.waypoints):
        raise ConfigError(f"--out: {str(out)!r} is the waypoints file; give another --out (it would be replaced)")
    if out.exists() and not args.overwrite:
        raise ConfigError(f"--out: {str(out)!r} exists; give --overwrite to replace it, or another --out")

    W = read_waypoints_csv(args.waypoints)
    check_waypoints(W, source=args.waypoints)
    if W.shape[1] == 3 and args.altitude is not None:
        raise ConfigError("--altitude applies to 2-D waypoints only; the waypoints have a z column")
    M = W.shape[0] - 1
    if args.durations is not None:
        T = np.asarray(_durations(args.durations))
        if len(T) != M:
            raise ConfigError(f"--durations has {len(T)} value{'s' * (len(T) != 1)}; {M + 1} waypoints need {M}")
    else:
        T = constant_speed_durations(W, speed)
    _check_piece_durations(T, "--durations" if args.durations is not None else
                           f"--speed {speed:g}" if args.speed is not None else f"the default speed {speed:g} m/s")

    notes = []
    weight = None
    if args.refine_time:
        t0 = time.perf_counter()
        ref = refine_durations(W, T, time_weight=args.time_weight, degree=degree, derivative=q)
        T, weight = ref.durations, ref.time_weight
        notes.append(f"durations refined in {(time.perf_counter() - t0) * 1e3:.1f} ms ({ref.iterations} iterations)")
    t0 = time.perf_counter()
    res = solve_min_snap(W, T, degree=degree, derivative=q, backend=args.qp)
    elapsed = time.perf_counter() - t0
    traj = res.trajectory
    _check_passes_waypoints(traj, W, T)
    if args.retime == "toppra":
        if not getattr(args, "verbose", False):
            # toppra logs its failures as warnings; the failure itself becomes our one-line error
            logging.getLogger("toppra").setLevel(logging.ERROR)
        rt = retime_toppra(traj, args.v_max, args.a_max, derivative=q, backend=args.qp)
        traj, weight = rt.trajectory, None  # toppra's time law is no optimum of any weight
        how = "toppra retimed" if rt.method == "toppra" else "scaled uniformly (toppra's refit was slower)"
        notes.append(f"{how}, {rt.toppra_duration:.3f} s time-optimal, v {rt.v_peak:.3f} m/s, a {rt.a_peak:.3f} m/s^2")
    elif args.v_max is not None or args.a_max is not None:
        # without a weight of the user's, refinement chose only the shares: fly them as fast as the limits allow
        sc = scale_to_limits(traj, args.v_max, args.a_max, allow_speedup=args.refine_time and args.time_weight is None)
        traj = sc.trajectory
        if weight is not None:
            weight = scaled_time_weight(weight, sc.alpha, q)
        notes.append(f"time x{sc.alpha:.4g} for the limits, v {sc.v_peak:.3f} m/s, a {sc.a_peak:.3f} m/s^2")
    if weight is not None:
        notes.append(f"time weight {weight:.4g}")
    altitude = ScenarioConfig.altitude if args.altitude is None else args.altitude
    write_uav_csv(traj, out, altitude=altitude)
    if traj.pieces > CRAZYFLIE_PIECES:
        print(f"mrfswarm: warning: {traj.pieces} pieces: a Crazyflie's trajectory memory holds {CRAZYFLIE_PIECES} "
              "(4096 bytes, raw format); give fewer waypoints to fly it on one", file=sys.stderr)
    print(f"{traj.pieces} pieces, {traj.duration:.3f} s, backend {res.backend}, "
          f"solved in {elapsed * 1e3:.2f} ms{''.join('; ' + n for n in notes)} -> {out}")
    return 0
