"""Fly an mrfswarm plan with Crazyswarm2 (written by ``mrfswarm run`` into ``<run>/crazyswarm2/``).

1. Check ``crazyflies.yaml`` beside this file: one robot ``cf<k>`` per planned robot (it
   flies ``../trajectories/robot_<k-1>.csv``), its radio ``uri`` and its
   ``initial_position`` (on the ground below the planned start). Place each Crazyflie there.
2. ``ros2 launch crazyflie launch.py crazyflies_yaml_file:=$PWD/crazyflies.yaml``
3. ``python3 fly.py``: loads every enabled robot's trajectory and refuses, before any radio
   link (and before importing Crazyswarm2's package), one that does not fit (raw pieces: at most 31 fit a Crazyflie's memory; for longer
   plans use ``../crazyflie/cflib_upload.py --compressed``, or, where ``../result.json`` says no format holds
   them, its ``crazyflie.advice``); connects, refuses a server whose
   robots are not this file's; uploads,
   takes off to the plan's altitude (a 3-D plan's: its highest start), goes to each start
   (a 3-D plan's own height), starts all trajectories at once
   (absolute positions: the plan's world frame is the motion-capture frame), lands. Take-off,
   go-to and landing last what ``maneuvers.yaml`` beside this file says (within the plan's limits;
   3 s each without it).
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
from pathlib import Path

import numpy as np
import yaml

HERE = Path(__file__).resolve().parent
TRAJECTORIES = HERE.parent / "trajectories"
MAX_RAW_PIECES = 31  # 4096-byte trajectory memory / 132 bytes a raw piece
SETTLE_S = 1.0
TRAJECTORY_ID = 0
#: take-off, go-to and landing without maneuvers.yaml (a folder written before it)
DEFAULT_MANEUVERS = {"takeoff_s": 3.0, "goto_s": 3.0, "land_s": 3.0, "land_height_m": 0.04}


def maneuvers() -> dict:
    """The take-off, go-to and landing durations (s) and the landing height (m): ``maneuvers.yaml`` beside this file."""
    path = HERE / "maneuvers.yaml"
    return {**DEFAULT_MANEUVERS, **(yaml.safe_load(path.read_text()) if path.is_file() else {})}


def robot_index(name: str) -> int:
    """``cf<k>`` flies the plan's robot ``k - 1``."""
    if not (name.startswith("cf") and name[2:].isdigit()):
        raise SystemExit(f"fly.py: robot name {name!r} in crazyflies.yaml is not cf<k>, as mrfswarm wrote it")
    return int(name[2:]) - 1


def enabled_robots() -> list[str]:
    """The names of the enabled robots of ``crazyflies.yaml`` beside this file (the robots this plan flies)."""
    robots = yaml.safe_load((HERE / "crazyflies.yaml").read_text())["robots"]
    return sorted(name for name, entry in robots.items() if entry.get("enabled", True))


def instead(robot: int) -> str:
    """What flies a robot whose raw pieces do not fit, as ``../result.json`` says (its ``crazyflie`` section):
    the compressed pieces where they fit and are certified, else why no format does and what to plan instead."""
    try:
        section = json.loads((HERE.parent / "result.json").read_text()).get("crazyflie") or {}
    except (OSError, ValueError):
        section = {}
    entry: dict = next((r for r in section.get("robots") or [] if r.get("robot") == robot), {})
    if entry.get("flies", "compressed") == "compressed" or not section.get("advice"):
        return "fly it compressed with ../crazyflie/cflib_upload.py --compressed --fly"
    return section["advice"]


def crazyflie_py():
    """Crazyswarm2's Python package, or a one-line refusal saying what provides it."""
    try:
        import crazyflie_py
        import crazyflie_py.uav_trajectory
    except ImportError as e:
        raise SystemExit(f"fly.py: Crazyswarm2's Python package crazyflie_py is not importable ({e}): source the "
                         "ROS 2 workspace where Crazyswarm2 is built (source install/setup.bash) and run fly.py "
                         "again") from None
    return crazyflie_py


def load(names: list[str]) -> dict:
    """Each robot's Crazyswarm2 ``Trajectory``, loaded from its CSV; refuses one that does not fit the memory.

    The CSVs' pieces (a header, then a row each) are counted before ``crazyflie_py`` is imported: a plan that
    does not fit is refused on a machine without the Crazyswarm2 workspace too."""
    paths = {}
    for name in names:
        path = TRAJECTORIES / f"robot_{robot_index(name)}.csv"
        if not path.is_file():
            raise SystemExit(f"fly.py: no trajectory {path} for {name}")
        pieces = sum(1 for line in path.read_text().splitlines()[1:] if line.strip())
        if pieces > MAX_RAW_PIECES:
            raise SystemExit(f"fly.py: {name}'s trajectory has {pieces} pieces; a Crazyflie holds {MAX_RAW_PIECES} "
                             f"raw pieces: {instead(robot_index(name))}")
        paths[name] = path
    Trajectory = crazyflie_py().uav_trajectory.Trajectory

    out = {}
    for name, path in paths.items():
        out[name] = traj = Trajectory()
        readable = loadable(path)
        try:
            traj.loadcsv(readable)  # a row a piece, as counted above
        finally:
            if readable != path:  # the two halves' temporary file
                readable.unlink(missing_ok=True)
    return out


def loadable(path: Path) -> Path:
    """``path``, or where a trajectory of one piece is written as two: Crazyswarm2's ``loadcsv`` reads the rows
    without ``ndmin=2``, and one row ended in "IndexError: invalid index to scalar variable" (a plan whose robots
    start at the goal: one hover piece). The halves are the same polynomial (its coefficients shifted to the
    second half's start), so the same flight."""
    lines = path.read_text().splitlines()
    rows = [line for line in lines[1:] if line.strip()]
    if len(rows) != 1:
        return path
    row = np.array(rows[0].split(","), dtype=float)
    half = row[0] / 2
    coefs = row[1:].reshape(-1, 8)  # x, y, z, yaw: powers 0..7 of the piece's own time
    shifted = np.array([np.polynomial.Polynomial(c)(np.polynomial.Polynomial([half, 1.0])).coef for c in coefs])
    shifted = np.pad(shifted, ((0, 0), (0, 8 - shifted.shape[1])))  # a constant composes to one coefficient
    body = [",".join(repr(float(v)) for v in [half, *part.ravel()]) for part in (coefs, shifted)]
    fd, name = tempfile.mkstemp(prefix=f"{path.stem}_", suffix=".csv")  # not in the run's folder
    with os.fdopen(fd, "w") as f:
        f.write("\n".join([lines[0], *body]) + "\n")
    return Path(name)


def start_of(traj) -> np.ndarray:
    """x, y, z at time 0 (the constant coefficients of the first piece)."""
    p = traj.polynomials[0]
    return np.array([p.px.p[0], p.py.p[0], p.pz.p[0]], dtype=float)


def main(argv: list[str] | None = None) -> None:
    argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter).parse_args(argv)
    trajectories = load(enabled_robots())  # every refusal before the radio link
    swarm = crazyflie_py().Crazyswarm()
    time_helper = swarm.timeHelper
    allcfs = swarm.allcfs
    by_name = allcfs.crazyfliesByName
    if sorted(by_name) != sorted(trajectories):  # takeoff and land command every robot the server knows
        raise SystemExit(f"fly.py: the Crazyswarm2 server flies {sorted(by_name)}, this plan {sorted(trajectories)}: "
                         "launch it with this folder's crazyflies.yaml")
    m = maneuvers()
    altitude = max(start_of(t)[2] for t in trajectories.values())
    duration = max(t.duration for t in trajectories.values())

    for name, traj in trajectories.items():
        by_name[name].uploadTrajectory(TRAJECTORY_ID, 0, traj)

    allcfs.takeoff(targetHeight=altitude, duration=m["takeoff_s"])
    time_helper.sleep(m["takeoff_s"] + SETTLE_S)
    for name, traj in trajectories.items():
        by_name[name].goTo(start_of(traj), 0.0, m["goto_s"])
    time_helper.sleep(m["goto_s"] + SETTLE_S)

    allcfs.startTrajectory(TRAJECTORY_ID, timescale=1.0, relative=False)  # all at once: the plan is synchronous
    time_helper.sleep(duration + SETTLE_S)

    allcfs.land(targetHeight=m["land_height_m"], duration=m["land_s"])
    time_helper.sleep(m["land_s"] + SETTLE_S)


if __name__ == "__main__":
    main()
