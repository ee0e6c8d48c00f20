"""Upload an mrfswarm plan straight to Crazyflies with cflib, and fly it (no ROS).

Written by ``mrfswarm run`` into ``<run>/crazyflie/``; needs ``pip install 'mrfswarm[crazyflie]'``
(cflib, and mrfswarm, whose :mod:`mrfswarm.export.cflib_` builds cflib's pieces).

    python cflib_upload.py [--compressed] [--fly] [--robots 0,1,...]

Radio addresses come from ``../crazyswarm2/crazyflies.yaml`` (``cf<k>`` is robot ``k - 1``).
Raw pieces (``Poly4D``) are those of ``../trajectories/robot_<i>.csv``; at most 31 fit.
``--compressed`` uploads the compressed pieces of ``compressed.json`` beside this file, the
ones whose decoded flight ``result.json`` certifies (``crazyflie.compressed``), and refuses
robots whose decoded flight it does not (``not_certified_robots``); their
positions are relative to ``origin_m``: the positioning system's origin must be there.
``--fly`` then takes off, goes to each start, starts all trajectories at once, and lands.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import yaml

HERE = Path(__file__).resolve().parent
PLAN = HERE.parent
TRAJECTORY_ID = 1
MEMORY_BYTES = 4096  # a Crazyflie's trajectory memory
SETTLE_S = 1.0
#: take-off, go-to and landing without crazyswarm2/maneuvers.yaml (a folder written before it)
DEFAULT_MANEUVERS = {"takeoff_s": 3.0, "goto_s": 3.0, "land_s": 3.0, "land_height_m": 0.04}


def uris(plan: Path = PLAN) -> dict[int, str]:
    """Robot index -> radio URI, from Crazyswarm2's ``crazyflies.yaml``."""
    robots = yaml.safe_load((plan / "crazyswarm2" / "crazyflies.yaml").read_text())["robots"]
    return {int(name[2:]) - 1: entry["uri"] for name, entry in robots.items() if entry.get("enabled", True)}


def maneuvers(plan: Path = PLAN) -> dict:
    """The take-off, go-to and landing durations (s) and the landing height (m) fly.py flies too:
    ``crazyswarm2/maneuvers.yaml`` (within the plan's limits)."""
    path = plan / "crazyswarm2" / "maneuvers.yaml"
    return {**DEFAULT_MANEUVERS, **(yaml.safe_load(path.read_text()) if path.is_file() else {})}


def pieces(robots: list[int], compressed: bool, plan: Path = PLAN) -> tuple[dict[int, list[Any]], np.ndarray]:
    """cflib elements per robot and the frame origin they are relative to (zero for raw pieces)."""
    from mrfswarm.export import cflib_
    from mrfswarm.trajectory import read_uav_csv

    if not compressed:
        out = {}
        for i in robots:
            tr = read_uav_csv(plan / "trajectories" / f"robot_{i}.csv", dim=4)
            out[i] = cflib_.raw_pieces(tr, 0.0)
        return out, np.zeros(3)
    uncertified = sorted(set(robots) & set(not_certified(plan)))
    if uncertified:
        raise SystemExit(f"cflib_upload.py: the compressed flight of robots {uncertified} is not certified "
                         "(result.json: crazyflie.compressed.not_certified_robots); upload the raw pieces instead "
                         "(without --compressed)")
    c = compressed_plan(plan)
    return {i: cflib_.compressed_elements(c, i) for i in robots}, c.origin


def not_certified(plan: Path = PLAN) -> list[int]:
    """The robots whose decoded compressed flight ``result.json`` does not certify (all, without a certificate)."""
    if not (plan / "result.json").is_file():
        raise SystemExit(f"cflib_upload.py: no result.json in {plan}: whether the compressed flight is certified "
                         "cannot be read; upload the raw pieces instead (without --compressed)")
    section = json.loads((plan / "result.json").read_text()).get("crazyflie") or {}
    compressed = section.get("compressed") or {}
    if "error" in compressed:  # no compressed flight was made (a flight too wide for its 16-bit millimetres)
        raise SystemExit(f"cflib_upload.py: this plan has no compressed flight: {compressed['error']}; upload the "
                         "raw pieces instead (without --compressed)")
    if "not_certified_robots" not in compressed:
        return list(range(len(section.get("robots") or [])))
    return [int(i) for i in compressed["not_certified_robots"]]


def compressed_plan(plan: Path = PLAN) -> Any:
    """The :class:`~mrfswarm.export.cflib_.Compressed` flight of ``compressed.json``."""
    from mrfswarm.export import cflib_

    d = json.loads((plan / "crazyflie" / "compressed.json").read_text())
    return cflib_.Compressed(np.array(d["origin_m"], dtype=float), [np.array(k, dtype=np.int64) for k in d["knots_ms"]],
                             [np.array(p, dtype=np.int64) for p in d["points_mm"]],
                             None if d["z_mm"] is None else int(d["z_mm"]),  # None: a 3-D flight's z is in the points
                             float(d["position_error_bound_m"]))


class UploadError(Exception):
    """A robot's trajectory not written. An exception, not ``SystemExit``: cflib's ``parallel_safe`` runs the
    upload in a thread, where a ``SystemExit`` ends the thread without a word and the flight went on."""


def size_of(elements: list[Any]) -> int:
    """Bytes ``elements`` take in the trajectory memory (cflib's own packing)."""
    return len(b"".join(bytes(e.pack()) for e in elements))


def refuse_oversized(elements: dict[int, list[Any]], compressed: bool, plan: Path = PLAN) -> None:
    """Before any radio link: refuse the robots whose trajectory does not fit the memory, in one line saying what
    flies them (the compressed pieces, or what ``result.json``'s ``crazyflie.advice`` says to plan instead)."""
    sizes = {i: size_of(e) for i, e in elements.items()}
    over = sorted(i for i, n in sizes.items() if n > MEMORY_BYTES)
    if not over:
        return
    section: dict = {}
    if (plan / "result.json").is_file():
        section = json.loads((plan / "result.json").read_text()).get("crazyflie") or {}
    flies = {r.get("robot"): r.get("flies", "compressed") for r in section.get("robots") or []}
    if section.get("advice") and not all(flies.get(i) == "compressed" for i in over):
        raise SystemExit(f"cflib_upload.py: {section['advice']}")
    raise SystemExit(f"cflib_upload.py: robots {over} take up to {max(sizes[i] for i in over)} bytes, more than a "
                     f"Crazyflie's {MEMORY_BYTES}-byte trajectory memory"
                     + ("" if compressed else "; upload them compressed (--compressed)"))


def upload(cf: Any, elements: list[Any], compressed: bool) -> int:
    """Write ``elements`` into ``cf``'s trajectory memory and define trajectory ``TRAJECTORY_ID``; the bytes used."""
    from cflib.crazyflie.high_level_commander import HighLevelCommander
    from cflib.crazyflie.mem import MemoryElement

    memory = cf.mem.get_mems(MemoryElement.TYPE_TRAJ)[0]
    memory.trajectory = list(elements)
    size = size_of(memory.trajectory)
    if size > memory.size:
        raise UploadError(f"{size} bytes do not fit the trajectory memory ({memory.size} bytes)"
                          + ("" if compressed else "; try --compressed"))
    if not memory.write_data_sync():
        raise UploadError(f"uploading to {getattr(cf, 'link_uri', cf)} failed")
    n = len(elements) - 2 if compressed else len(elements)  # compressed: not the start and end elements
    kind = HighLevelCommander.TRAJECTORY_TYPE_POLY4D_COMPRESSED if compressed else HighLevelCommander.TRAJECTORY_TYPE_POLY4D
    cf.high_level_commander.define_trajectory(TRAJECTORY_ID, 0, n, type=kind)
    return size


def stored(elements: list[Any]) -> tuple[list[int], list[int]]:
    """Compressed elements as the Crazyflie stores them (cflib's own packing, read back): the start (x, y, z in
    millimetres from the origin) and each segment's duration in milliseconds. The elements' floats carry half a
    unit more than the stored value (cflib's encoders truncate), so they are not read directly."""
    from mrfswarm.export import cflib_

    start, segments = cflib_.parse_compressed(cflib_.pack(elements))
    return start[:3], [ms for ms, _ in segments]


def start_of(elements: list[Any], compressed: bool) -> tuple[float, float, float]:
    """Where the trajectory starts, in the frame it is flown in."""
    if compressed:
        x, y, z = (v / 1000.0 for v in stored(elements)[0])  # metres from the origin
        return (x, y, z)
    e = elements[0]
    return (e.x.values[0], e.y.values[0], e.z.values[0])


def takeoff_altitude(elements: dict[int, list[Any]], compressed: bool) -> float:
    """The height every robot takes off to: the highest start (a 2-D plan's altitude; a 3-D plan's top start), so
    that no robot goes to its start through another's, as ``fly.py`` does."""
    return max(start_of(e, compressed)[2] for e in elements.values())


def duration_of(elements: list[Any], compressed: bool) -> float:
    """Seconds the trajectory lasts as the Crazyflie flies it."""
    if compressed:
        return sum(stored(elements)[1]) / 1000.0
    return float(sum(e.duration for e in elements))


def open_swarm(uris: list[str], factory: Any) -> Any:
    """A cflib ``Swarm`` of ``uris`` with its links open, or one line saying why not (no Crazyradio, a robot that does
    not answer): cflib logs a traceback for each link it cannot open, and its swarm raises from a thread, pages of
    them in all."""
    from cflib.crazyflie.swarm import Swarm

    swarm = Swarm(uris, factory=factory)
    quiet = logging.getLogger("cflib")
    level = quiet.level
    quiet.setLevel(logging.CRITICAL)  # its tracebacks of a link that fails; the cause is said below
    try:
        swarm.open_links()
    except Exception as e:
        raise SystemExit(f"cflib_upload.py: cannot open the links to {', '.join(uris)}: {cause(e)}") from None
    finally:
        quiet.setLevel(level)
    return swarm


def cause(e: BaseException) -> str:
    """The first line of the exception at the root of ``e`` (cflib's swarm raises its own around a thread's)."""
    root = e
    while (root.__cause__ or root.__context__) is not None:
        root = root.__cause__ or root.__context__  # type: ignore[assignment]
    return (str(root).strip().splitlines() or [type(root).__name__])[0]


def together(swarm: Any, what: str, func: Any) -> None:
    """``func`` on every robot of ``swarm`` at once; a robot that fails stops the script in one line (before any
    later step: a robot whose upload failed would fly the trajectory an earlier upload left in its memory)."""
    try:
        swarm.parallel_safe(func)
    except Exception as e:
        raise SystemExit(f"cflib_upload.py: {what} failed: {cause(e)}") from None


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--compressed", action="store_true", help="compressed pieces (fit 131 instead of 31; 90 in a 3-D plan, whose z is stored too)")
    ap.add_argument("--fly", action="store_true", help="after uploading, take off, fly and land")
    ap.add_argument("--robots", default=None, help="comma-separated robot indices (default: all in the yaml)")
    args = ap.parse_args(argv)
    addresses = uris()
    robots = sorted(addresses) if args.robots is None else [int(v) for v in args.robots.split(",")]
    missing = [i for i in robots if i not in addresses]
    if missing:
        raise SystemExit(f"cflib_upload.py: robots {missing} have no enabled entry in crazyswarm2/crazyflies.yaml")
    elements, origin = pieces(robots, args.compressed)
    refuse_oversized(elements, args.compressed)
    if args.compressed and np.any(origin != 0):
        print(f"compressed positions are relative to {origin.tolist()} m: the positioning system's origin must be there")

    import cflib.crtp
    from cflib.crazyflie.swarm import CachedCfFactory

    cflib.crtp.init_drivers()
    by_uri = {addresses[i]: i for i in robots}
    swarm = open_swarm(list(by_uri), CachedCfFactory(rw_cache=str(HERE / "cache")))
    try:
        together(swarm, "the upload", lambda scf: print(
            scf.cf.link_uri, upload(scf.cf, elements[by_uri[scf.cf.link_uri]], args.compressed), "bytes"))
        if not args.fly:
            return 0
        swarm.reset_estimators()
        m = maneuvers()
        altitude = takeoff_altitude(elements, args.compressed)
        together(swarm, "the take-off", lambda scf: scf.cf.high_level_commander.takeoff(altitude, m["takeoff_s"]))
        time.sleep(m["takeoff_s"] + SETTLE_S)
        together(swarm, "the go-to", lambda scf: scf.cf.high_level_commander.go_to(
            *start_of(elements[by_uri[scf.cf.link_uri]], args.compressed), 0.0, m["goto_s"]))
        time.sleep(m["goto_s"] + SETTLE_S)
        together(swarm, "the start", lambda scf: scf.cf.high_level_commander.start_trajectory(
            TRAJECTORY_ID, 1.0, relative_position=False))
        time.sleep(max(duration_of(e, args.compressed) for e in elements.values()) + SETTLE_S)
        together(swarm, "the landing", lambda scf: scf.cf.high_level_commander.land(m["land_height_m"], m["land_s"]))
        time.sleep(m["land_s"] + SETTLE_S)
        together(swarm, "the stop", lambda scf: scf.cf.high_level_commander.stop())
    finally:
        swarm.close_links()
    return 0


def run(argv: list[str] | None = None) -> int:
    """:func:`main`, with a missing package or a plan the Crazyflie cannot hold as one line (what to install or
    change), not a traceback."""
    try:
        from mrfswarm.errors import MrfswarmError
    except ImportError as e:
        raise SystemExit(f"cflib_upload.py: {e}: pip install 'mrfswarm[crazyflie]' (mrfswarm and cflib)") from None
    try:
        return main(argv)
    except ImportError as e:
        raise SystemExit(f"cflib_upload.py: {e}: pip install 'mrfswarm[crazyflie]' (cflib)") from None
    except MrfswarmError as e:
        raise SystemExit(f"cflib_upload.py: {e}") from None


if __name__ == "__main__":
    sys.exit(run())
