"""Where the robots of a flight stop: each stop against the discrete plan's waits and turns.

A stop is what the flight-quality bench counts (:func:`mrfswarm.flight_quality.count_stops`: slower than
0.05 m/s strictly inside a robot's flight). Each stop's first sample falls in some MRF step; it is put in
one of these classes by the robot's cells around that step:

- ``wait N``: the robot waits in the plan at that step or the one before or after, in a run of N waits
  (``1``, ``2-8``, ``>8``: the creep of the default profiles covers runs of up to 8), and the moves
  before and after the run turn by ``<90`` or ``>=90`` degrees (``-``: the run starts or ends the flight);
- ``moving A``: it moves in the plan there, the moves before and at that step turning by A degrees.

    python experiments/bench/stop_census.py [--cases big200] [--set KEY=VALUE]

The census of docs/flight_quality.md's "Not yet reached" (fourteenth session): big200's 199 stops.
"""

from __future__ import annotations

import argparse
import collections
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from flight_quality import VARIANTS, case_config  # noqa: E402

#: Wait runs up to this long are the ones the default profiles creep through (receding_horizon.CREEP_WAITS).
CREEP_RUN = 8


def _turn(before: np.ndarray, after: np.ndarray) -> float:
    cos = float(before @ after) / max(float(np.linalg.norm(before) * np.linalg.norm(after)), 1e-12)
    return float(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))))


def stop_steps(trajectory, knots: np.ndarray, rate_hz: float, speed: float) -> list[int]:
    """The MRF step in which each stop of one robot's flight starts."""
    t = np.linspace(0.0, trajectory.duration, max(2, int(np.ceil(trajectory.duration * rate_hz)) + 1))
    v = np.linalg.norm(trajectory.evaluate(t, 1), axis=-1)
    moving = np.flatnonzero(v >= speed)
    if len(moving) == 0:
        return []
    slow = v[moving[0]:moving[-1] + 1] < speed
    starts = np.flatnonzero(slow & ~np.concatenate([[False], slow[:-1]]))
    return [int(np.searchsorted(knots, t[moving[0] + s], side="right") - 1) for s in starts]


def classify(moves: np.ndarray, step: int) -> str:
    """The class (module docstring) of a stop in ``step`` of a robot with plan moves ``moves`` (T, d)."""
    T = len(moves)
    step = min(max(step, 0), T - 1)
    still = ~np.any(moves != 0, axis=1)
    near = [s for s in (step, step - 1, step + 1) if 0 <= s < T and still[s]]
    if not near:
        return f"moving {round(_turn(moves[step - 1], moves[step])) if step > 0 else 0}"
    a = b = near[0]
    while a > 0 and still[a - 1]:
        a -= 1
    while b + 1 < T and still[b + 1]:
        b += 1
    length = b - a + 1
    run = "1" if length == 1 else f"2-{CREEP_RUN}" if length <= CREEP_RUN else f">{CREEP_RUN}"
    if a == 0 or b + 1 == T:
        return f"wait {run}, -"
    return f"wait {run}, {'<90' if _turn(moves[a - 1], moves[b + 1]) < 90 else '>=90'}"


def census(case: str, variant: str, overrides: list[str]) -> tuple[collections.Counter, int]:
    from mrfswarm.config import apply_overrides, from_dict
    from mrfswarm.flight_quality import STOP_RATE_HZ, STOP_SPEED
    from mrfswarm.pipeline import plan

    data, base = case_config(case)
    cfg = from_dict(apply_overrides(data, ["simulation.enabled=false", *VARIANTS[variant], *overrides]), base)
    r = plan(cfg, progress=False)
    c, moves = r.continuous, np.diff(r.discrete.paths, axis=0)
    if c is None:
        raise SystemExit(f"{case}: the run has no continuous plan (smoothing.enabled = false?)")
    counts: collections.Counter = collections.Counter()
    for i, tr in enumerate(c.trajectories):
        for step in stop_steps(tr, c.knot_times, STOP_RATE_HZ, STOP_SPEED):
            counts[classify(moves[:, i], step)] += 1
    return counts, r.scenario.n_robots


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cases", default="big200")
    ap.add_argument("--variant", default="default", choices=sorted(VARIANTS))
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    args = ap.parse_args()
    for case in args.cases.split(","):
        counts, robots = census(case, args.variant, args.set)
        total = sum(counts.values())
        print(f"{case} ({args.variant}): {total} stops, {total / robots:.2f} per robot")
        for key, n in counts.most_common():
            print(f"  {key:<16} {n:>5}")


if __name__ == "__main__":
    main()
