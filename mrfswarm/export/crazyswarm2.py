"""Crazyswarm2's ``crazyflies.yaml`` for a plan, and the flight scripts beside it.

Crazyswarm2 (``crazyflie`` ROS 2 package) reads ``crazyflies.yaml`` with
``yaml.safe_load``: ``robots`` (name -> ``enabled``, ``uri``, ``initial_position``,
``type``), ``robot_types`` (what each ``type`` names: motion capture, battery) and ``all``
(firmware parameters for every robot: the high-level commander on). Robot ``i`` of the plan
is ``cf<i+1>``, on ``radio://0/80/2M/E7E7E7E7<i+1 in hex>`` (four hex digits past 255
robots; Crazyswarm2 itself identifies a robot by the URI's last byte, so keep a flight
below 256 robots or edit the addresses), on the ground below its planned start (z = 0: that is
where the robot sits when motion capture first finds it; the flight takes off and goes to the
start, at the altitude in a 2-D plan and at the start's own height in a 3-D one).
"""

from __future__ import annotations

import logging
import math
import shutil
from collections.abc import Sequence
from functools import partial
from pathlib import Path

import numpy as np
import yaml

log = logging.getLogger(__name__)

URI = "radio://0/80/2M/E7E7E7E7{id:02X}"
URI_WIDE = "radio://0/80/2M/E7E7E7{id:04X}"
ROBOT_TYPE = "cf21"
SCRIPTS = Path(__file__).parent / "scripts"
#: The firmware's take-off, go-to and landing fly this polynomial of t / T over [0, 1] from rest to rest (speed,
#: acceleration and jerk zero at both ends: crazyflie-firmware's planner.c, ``piecewise_plan_7th_order_no_jerk``).
REST_TO_REST = np.polynomial.Polynomial([0, 0, 0, 0, 35, -84, 70, -20])
#: The scripts' take-off, go-to and landing last at least this long (their one duration before the limits set it).
MANEUVER_MIN_S = 3.0
#: The height the scripts land to (the firmware's land command stops there and the motors go off).
LAND_HEIGHT_M = 0.04


def robot_name(i: int) -> str:
    """Robot ``i`` of the plan is ``cf<i+1>``."""
    return f"cf{i + 1}"


def crazyflies_config(starts: np.ndarray, uri: str | None = None) -> dict:
    """The content of ``crazyflies.yaml``: one enabled robot per start, (N, d) metres.

    ``initial_position`` is the start's x, y on the ground (z = 0), in a 2-D or 3-D plan.
    """
    starts = np.asarray(starts, dtype=float)
    uri = uri or (URI if len(starts) <= 255 else URI_WIDE)
    robots = {robot_name(i): {"enabled": True, "uri": uri.format(id=i + 1),
                              "initial_position": [float(s[0]), float(s[1]), 0.0],
                              "type": ROBOT_TYPE}
              for i, s in enumerate(starts)}
    return {
        "fileversion": 3,
        "robots": robots,
        "robot_types": {ROBOT_TYPE: {
            "motion_capture": {"enabled": True, "tracking": "librigidbodytracker",
                               "marker": "default_single_marker", "dynamics": "default"},
            "big_quad": False,
            "battery": {"voltage_warning": 3.8, "voltage_critical": 3.7},
        }},
        "all": {
            "firmware_logging": {"enabled": False},
            "firmware_params": {"commander": {"enHighLevel": 1}, "stabilizer": {"estimator": 2, "controller": 2},
                                "locSrv": {"extPosStdDev": 1e-3, "extQuatStdDev": 0.05}},
            "reference_frame": "world",
            "broadcasts": {"num_repeats": 15, "delay_between_repeats_ms": 1},
        },
    }


def shared_ground(starts: np.ndarray, distance: float) -> list[tuple[int, int]]:
    """Pairs of robots whose ground spots (``initial_position``: x, y below the start) are nearer than
    ``distance``: in a 3-D plan, robots that start one above the other. They cannot both sit there, and
    taking off straight up (fly.py, cflib_upload.py) would fly one into the other."""
    xy = np.asarray(starts, dtype=float)[:, :2]
    d = np.linalg.norm(xy[:, None] - xy[None], axis=-1)
    i, k = np.nonzero(np.triu(d < distance, 1))
    return [(int(a), int(b)) for a, b in zip(i, k)]


def _peak(k: int) -> float:
    """The largest |k-th derivative| of :data:`REST_TO_REST` over [0, 1] (k = 1: 35/16)."""
    d = REST_TO_REST.deriv(k)
    roots = np.asarray(d.deriv().roots(), dtype=complex)
    at = [0.0, 1.0] + [float(r.real) for r in roots if abs(r.imag) < 1e-9 and 0.0 <= float(r.real) <= 1.0]
    return max(abs(float(d(t))) for t in at)


def maneuver_duration(distance: float, v_max: float, a_max: float, j_max: float,
                      least: float = MANEUVER_MIN_S) -> float:
    """Seconds the firmware's maneuver (:data:`REST_TO_REST`) needs over ``distance`` metres to stay within the
    limits, at least ``least``: over d in T seconds its peak speed is 35/16 d / T, its peak acceleration 7.51 d / T^2
    and its peak jerk 52.5 d / T^3."""
    d = abs(float(distance))
    return max(float(least), _peak(1) * d / v_max, math.sqrt(_peak(2) * d / a_max), (_peak(3) * d / j_max) ** (1 / 3))


def maneuvers(start_z: np.ndarray, end_z: np.ndarray, v_max: float, a_max: float, j_max: float) -> dict:
    """The durations the scripts fly their maneuvers in, within the plan's limits (:func:`maneuver_duration`):
    ``takeoff_s`` from the ground (z = 0) up to the highest start, ``goto_s`` from there to each start (straight
    down to it: the robots take off below their starts), ``land_s`` from each end down to ``land_height_m``. A 2-D
    plan's starts and ends are at its altitude. (At the old 3 s each, a take-off to 4.5 m peaked at 3.3 m/s.)"""
    start_z, end_z = np.asarray(start_z, dtype=float), np.asarray(end_z, dtype=float)
    top = float(start_z.max())
    return {"takeoff_s": maneuver_duration(top, v_max, a_max, j_max),
            "goto_s": maneuver_duration(float(np.max(top - start_z)), v_max, a_max, j_max),
            "land_s": maneuver_duration(float(np.max(end_z - LAND_HEIGHT_M)), v_max, a_max, j_max),
            "land_height_m": LAND_HEIGHT_M,
            "limits": {"v_max": float(v_max), "a_max": float(a_max), "j_max": float(j_max)}}


def lowest_points(trajectories: Sequence, per_piece: int = 64) -> np.ndarray:
    """(N,) the lowest z each 3-D trajectory reaches (sampled, ``per_piece`` times per piece and at its knots)."""
    out = []
    for tr in trajectories:
        edges = np.concatenate([[0.0], np.cumsum(tr.durations)])
        t = np.unique(np.concatenate([np.linspace(a, b, per_piece + 1) for a, b in zip(edges[:-1], edges[1:])]))
        out.append(float(np.asarray(tr.evaluate(t))[:, 2].min()))
    return np.array(out)


def below_ground(lowest: np.ndarray, radius: float) -> np.ndarray:
    """The robots whose flight comes nearer than ``radius`` to the ground of the export (z = 0, where
    crazyflies.yaml places them): their lowest z (:func:`lowest_points`) below ``radius``."""
    return np.flatnonzero(np.asarray(lowest, dtype=float) < radius)


def blocked_columns(occupied: np.ndarray, origin: np.ndarray, resolution: float, xy: np.ndarray, top: np.ndarray,
                    radius: float) -> np.ndarray:
    """The robots whose vertical column, from the ground (z = 0) up to ``top`` (N,) at ``xy`` (N, 2), holds an
    occupied voxel within ``radius`` of it: a 3-D map (``occupied`` (W, H, D), voxel (i, j, k) centred at
    ``origin + resolution * (i, j, k)``). The scripts take off straight up to the highest start and land
    straight down: through a shelf over a robot's ground spot, were it not named."""
    occupied = np.asarray(occupied, dtype=bool)
    origin = np.asarray(origin, dtype=float)
    half = resolution / 2
    out = []
    for (x, y), z in zip(np.asarray(xy, dtype=float), np.asarray(top, dtype=float)):
        lo = np.floor((np.array([x, y]) - radius - origin[:2]) / resolution + 0.5).astype(int)
        hi = np.floor((np.array([x, y]) + radius - origin[:2]) / resolution + 0.5).astype(int)
        k = np.arange(occupied.shape[2])
        zc = origin[2] + resolution * k
        layers = k[(zc + half > 0.0) & (zc - half < z + radius)]
        hit = False
        for i in range(max(lo[0], 0), min(hi[0], occupied.shape[0] - 1) + 1):
            for j in range(max(lo[1], 0), min(hi[1], occupied.shape[1] - 1) + 1):
                c = origin[:2] + resolution * np.array([i, j])
                gap = np.maximum(np.abs(np.array([x, y]) - c) - half, 0.0)
                if np.hypot(*gap) < radius and occupied[i, j, layers].any():
                    hit = True
        out.append(hit)
    return np.flatnonzero(out)


def write_crazyswarm2(starts: np.ndarray, out: Path, radius: float = 0.0,
                      lowest: np.ndarray | None = None, columns: tuple[np.ndarray, np.ndarray] | None = None,
                      ends: np.ndarray | None = None, maneuver: dict | None = None,
                      altitude: float | None = None, floor: float | None = None) -> list[Path]:
    """``out/crazyswarm2/crazyflies.yaml``, ``out/crazyswarm2/fly.py``, ``out/crazyflie/cflib_upload.py`` and, given
    ``maneuver`` (:func:`maneuvers`), ``out/crazyswarm2/maneuvers.yaml``, the scripts' take-off, go-to and landing
    durations (without it the scripts fly each in :data:`MANEUVER_MIN_S`).

    Robots whose ground spots come nearer than ``2 radius`` (:func:`shared_ground`) are named in a warning
    and in the file's comments: their take-off is not the scripts' to fly; robots that end so (``ends``, a 3-D
    plan's robots one above the other at the goal), their landing, straight down onto one another. So are, in a 3-D plan (``lowest``:
    each robot's lowest z), the robots that fly nearer than ``radius`` to the ground the export takes off
    from, z = 0 (:func:`below_ground`): a 3-D map's floor is at ``origin[2] - resolution / 2``, by default
    below 0, and flown as planned they would go into the floor of the room. ``columns``: the robots whose
    take-off and whose landing columns are blocked (:func:`blocked_columns`), named in a warning too. ``altitude``:
    a 2-D plan's flight altitude, said in a warning when it is below ``radius`` (the robots would touch the ground).
    ``floor``: a 3-D map's floor, ``origin[2] - resolution / 2``, said in a warning when it is above the landing
    height: the robots sit on the ground at z = 0, below the map, and take off and land through what the plan
    counts as a wall (off the map)."""
    from mrfswarm.atomic import atomic_write

    header = "# Crazyswarm2 robots of this mrfswarm run: cf<k> flies trajectories/robot_<k-1>.csv (see fly.py)\n"
    texts = []
    stacked = (("start", starts, "crazyflies.yaml places them there; put one elsewhere and fly it to its start by "
                "hand (fly.py and cflib_upload.py take off straight up), or give scenario.start positions one per "
                "ground spot"),
               ("end", ends, "fly.py and cflib_upload.py land every robot straight down at once, one onto the other; "
                "land them one at a time, after flying one aside, or give the goal room for the swarm on one level"))
    for where, points, advice in stacked:
        pairs = shared_ground(points, 2 * radius) if radius > 0 and points is not None else []
        if pairs:
            names = ", ".join(f"{robot_name(i)} and {robot_name(k)}" for i, k in pairs[:6])
            more = f" and {len(pairs) - 6} more pairs" if len(pairs) > 6 else ""
            texts.append(f"robots {where} above the same ground spot ({names}{more}): {advice}")
    z_min = None if lowest is None else np.asarray(lowest, dtype=float)
    low = below_ground(z_min, radius) if z_min is not None else np.array([], dtype=int)
    if z_min is not None and len(low):
        worst = low[np.argsort(z_min[low])]
        names = ", ".join(f"{robot_name(int(i))} down to z = {round(float(z_min[i]), 3) + 0.0:g} m" for i in worst[:3])
        more = f" and {len(low) - 3} more" if len(low) > 3 else ""
        texts.append(f"{len(low)} robot{'s' * (len(low) != 1)} {'fly' if len(low) != 1 else 'flies'} nearer than the robot radius ({radius:g} m) to "
                     f"the ground at z = 0 that crazyflies.yaml takes off from ({names}{more}): put the map's floor "
                     f"at z = 0 (origin[2] = resolution / 2) and plan again before flying it")
    if altitude is not None and altitude < radius:
        texts.append(f"the plan flies at scenario.altitude = {altitude:g} m, nearer than the robot radius ({radius:g} m) "
                     f"to the ground that crazyflies.yaml takes off from: raise scenario.altitude before flying it")
    if floor is not None and floor > LAND_HEIGHT_M:
        texts.append(f"the map's floor is at z = {floor:g} m, above the ground at z = 0 that crazyflies.yaml places the "
                     f"robots on: fly.py and cflib_upload.py take off from there and land to z = {LAND_HEIGHT_M:g} m "
                     f"through the space below the map, which the plan counts as a wall; put the map's floor at z = 0 "
                     f"(origin[2] = resolution / 2, the space below it in the map) and plan again before flying it")
    for robots, what in zip(columns or (), ("take off straight up through", "land straight down through")):
        if len(robots):
            names = ", ".join(robot_name(int(i)) for i in robots[:6]) + (f" and {len(robots) - 6} more"
                                                                         if len(robots) > 6 else "")
            texts.append(f"{names} would {what} an obstacle over {'its' if len(robots) == 1 else 'their'} ground "
                         f"spot{'s' * (len(robots) != 1)} (fly.py and cflib_upload.py fly "
                         f"every robot up to the highest start and land them straight down): fly them to their "
                         f"starts and from their ends by hand, or plan starts and goal with a free sky above")
    for text in texts:
        log.warning("crazyswarm2: %s", text)
        header += f"# WARNING: {text}\n"
    written = [atomic_write(out / "crazyswarm2" / "crazyflies.yaml", lambda p: p.write_text(
        header + yaml.safe_dump(crazyflies_config(starts), sort_keys=False)))]
    if maneuver is not None:
        note = ("# the take-off, go-to and landing of fly.py and cflib_upload.py: the firmware flies each as a 7th-order\n"
                "# polynomial from rest to rest; these durations keep its peaks within the plan's limits\n")
        written.append(atomic_write(out / "crazyswarm2" / "maneuvers.yaml", lambda p: p.write_text(
            note + yaml.safe_dump(maneuver, sort_keys=False))))
    for folder, script in (("crazyswarm2", "fly.py"), ("crazyflie", "cflib_upload.py")):
        source = SCRIPTS / script
        written.append(atomic_write(out / folder / script, partial(shutil.copyfile, source)))
    return written


def starts_of(trajectories: Sequence) -> np.ndarray:
    """(N, d) every trajectory's position at time 0."""
    return np.array([tr.evaluate(0.0) for tr in trajectories])
