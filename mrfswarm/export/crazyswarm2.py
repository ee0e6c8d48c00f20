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
            "motion_capture": {"tracking": "librigidbodytracker", "marker": "default_single_marker",
                               "dynamics": "default"},
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


def write_crazyswarm2(starts: np.ndarray, out: Path, radius: float = 0.0) -> list[Path]:
    """``out/crazyswarm2/crazyflies.yaml``, ``out/crazyswarm2/fly.py`` and ``out/crazyflie/cflib_upload.py``.

    Robots whose ground spots come nearer than ``2 radius`` (:func:`shared_ground`) are named in a warning
    and in the file's comments: their take-off is not the scripts' to fly."""
    from mrfswarm.atomic import atomic_write

    header = "# Crazyswarm2 robots of this mrfswarm run: cf<k> flies trajectories/robot_<k-1>.csv (see fly.py)\n"
    pairs = shared_ground(starts, 2 * radius) if radius > 0 else []
    if pairs:
        names = ", ".join(f"{robot_name(i)} and {robot_name(k)}" for i, k in pairs)
        text = (f"robots start above the same ground spot ({names}): crazyflies.yaml places them there; put "
                f"one elsewhere and fly it to its start by hand (fly.py and cflib_upload.py take off straight up)")
        log.warning("crazyswarm2: %s", text)
        header += f"# WARNING: {text}\n"
    written = [atomic_write(out / "crazyswarm2" / "crazyflies.yaml", lambda p: p.write_text(
        header + yaml.safe_dump(crazyflies_config(starts), sort_keys=False)))]
    for folder, script in (("crazyswarm2", "fly.py"), ("crazyflie", "cflib_upload.py")):
        source = SCRIPTS / script
        written.append(atomic_write(out / folder / script, partial(shutil.copyfile, source)))
    return written


def starts_of(trajectories: Sequence) -> np.ndarray:
    """(N, d) every trajectory's position at time 0."""
    return np.array([tr.evaluate(0.0) for tr in trajectories])
