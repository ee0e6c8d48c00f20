"""The fast speed profile: a window's first attempt, on the steps it flies, the bold profile's tail after them."""

from __future__ import annotations

import numpy as np
import pytest

import mrfswarm
import mrfswarm.continuous.receding_horizon as rh_mod
from mrfswarm.config import from_dict
from mrfswarm.continuous.receding_horizon import RecedingHorizon


def profile(rh: RecedingHorizon, name: str, a: int, b: int) -> np.ndarray:
    """The attempt durations of profile ``name`` for window a..b (its own, or the window braking to rest at b)."""
    p = rh.profiles[[n for n, _, _ in rh_mod.PROFILES].index(name)]
    return np.maximum(p.durations[a:b], p.window(a, b))


@pytest.fixture(scope="module")
def doorway():
    """5 robots through a 3-cell door in a wall across a 30 x 20 map (the flight-quality bench's doorway)."""
    rows = ["".join("@" if x == 15 and not 9 <= y <= 11 else "." for x in range(30)) for y in range(20)]
    scn = {"map": {"kind": "ascii", "rows": rows}, "goal": [25, 10],
           "start": {"center": [6, 10], "n_robots": 5, "sigma": 1.0, "seed": 0}}
    cfg = from_dict({"scenario": scn, "interaction": {"k": 3}, "smoothing": {"enabled": False},
                     "simulation": {"enabled": False}})
    result = mrfswarm.plan(cfg, progress=False)
    return RecedingHorizon(result.discrete.paths, result.scenario.grid, cfg.smoothing, cfg.scenario.robot_radius,
                           workers=1)


def test_the_fast_attempt_flies_its_steps_and_brakes_as_the_bold_one(doorway, monkeypatch):
    rh = doorway
    tried: list[tuple[int, np.ndarray]] = []
    solve = rh._solve

    def spy(a, b, start, durations, *args, **kwargs):
        tried.append((a, np.array(durations)))
        return solve(a, b, start, durations, *args, **kwargs)

    monkeypatch.setattr(rh, "_solve", spy)
    plan = rh.run()
    assert plan.certificate.ok
    fast_windows = [w for w in plan.windows if w.attempt == "fast"]
    assert len(fast_windows) >= 3  # most windows of this map take it
    for w in plan.windows:
        first = next(d for a, d in tried if a == w.a)  # each window's first attempt
        fast, bold = profile(rh, "fast", w.a, w.b), profile(rh, "nominal", w.a, w.b)
        np.testing.assert_array_equal(first[:w.c - w.a], fast[:w.c - w.a])
        np.testing.assert_array_equal(first[w.c - w.a:], bold[w.c - w.a:])
        if w.attempt == "fast":
            np.testing.assert_array_equal(w.durations, first)
    # where the windows flew it, faster than the bold profile
    flown = sum(w.durations[:w.c - w.a].sum() for w in fast_windows)
    assert flown < 0.95 * sum(profile(rh, "nominal", w.a, w.b)[:w.c - w.a].sum() for w in fast_windows)
