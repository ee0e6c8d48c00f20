"""The fast speed profile: a window's first attempt, on the steps it flies, the bold profile's tail after them."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import mrfswarm
import mrfswarm.continuous.receding_horizon as rh_mod
from mrfswarm.config import from_dict, load_config
from mrfswarm.continuous.receding_horizon import RecedingHorizon
from support.attempts import unfollowed, unled, unretimed
from support.repository import EXPERIMENTS


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
    # the plan it was seen on: its waits merged without a flight model (a cruise speed set for the discrete stage
    # only; the windows below fly the default profiles)
    cfg = from_dict({"scenario": scn, "interaction": {"k": 3}, "smoothing": {"enabled": False, "speed": 1.25},
                     "simulation": {"enabled": False}})
    result = mrfswarm.plan(cfg, progress=False)
    return RecedingHorizon(result.discrete.paths, result.scenario.grid, dataclasses.replace(cfg.smoothing, speed=None),
                           cfg.scenario.robot_radius, workers=1)


def test_the_fast_attempt_flies_its_steps_and_brakes_as_the_bold_one(doorway, monkeypatch):
    rh = doorway
    monkeypatch.setattr(rh, "leading", None)  # the attempt before it, where sooner (tests/continuous/test_leading.py)
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


def _arena() -> RecedingHorizon:
    """8 robots of radius 0.1 m through a 6 x 3.5 m arena of 0.25 m cells between two pillars (the
    flight-quality bench's arena8)."""
    occ = np.zeros((24, 14), dtype=bool)
    occ[11:13, 0:5] = True
    occ[11:13, 9:14] = True
    rows = ["".join("@" if occ[x, y] else "." for x in range(24)) for y in range(14)]
    starts = [[0.5, y] for y in (0.75, 1.5, 2.25, 3.0)] + [[1.0, y] for y in (0.75, 1.5, 2.25, 3.0)]
    scn = {"map": {"kind": "ascii", "rows": rows, "resolution": 0.25}, "start": {"positions": starts},
           "goal": [5.25, 1.75], "robot_radius": 0.1, "goal_radius": 0.75}
    # the plan it was seen on: unstraightened, merged without a flight model (a cruise speed set for the
    # discrete stage only; the windows below fly the default profiles)
    cfg = from_dict({"scenario": scn, "interaction": {"k": 3},
                     "smoothing": {"enabled": False, "v_max": 1.0, "speed": 1.0},
                     "simulation": {"enabled": False}, "mrf": {"straighten": False}})
    result = mrfswarm.plan(cfg, progress=False)
    return RecedingHorizon(result.discrete.paths, result.scenario.grid, dataclasses.replace(cfg.smoothing, speed=None),
                           cfg.scenario.robot_radius, workers=1)


def test_the_last_window_brakes_a_little_longer_before_it_falls_back(monkeypatch):
    """The arena's last window is infeasible at its fast durations by a few per cent of its final braking step;
    the bold durations, every step longer, flew its last four steps in 1.95 s. With that step longer it flies
    the fast durations otherwise. (Since the window also tries the fast attempt with its first step as the
    window before planned it, the arena's last window flies that one: it is left out here; and the whole flight,
    16 steps, is re-timed after its windows: not here.)"""
    unfollowed(monkeypatch)
    unretimed(monkeypatch)
    unled(monkeypatch)
    rh = _arena()
    plan = rh.run()
    last = plan.windows[-1]
    assert plan.certificate.ok and last.b == rh.T
    assert last.failed and last.failed[0].startswith("fast")  # the fast attempt itself fails
    factor = rh_mod.FINAL_BRAKING[0]
    assert last.attempt == f"fast, braking x{factor:g}"
    fast = profile(rh, "fast", last.a, last.b)
    np.testing.assert_allclose(last.durations, np.concatenate([fast[:-1], fast[-1:] * factor]))
    monkeypatch.setattr(rh_mod, "FINAL_BRAKING", ())
    before = _arena().run()
    assert before.windows[-1].attempt == "nominal"
    assert plan.makespan_s < before.makespan_s - 0.2


def _rooms() -> RecedingHorizon:
    """experiments/maps/rooms_01.toml: 5 robots through the doors of a room map."""
    cfg = load_config(EXPERIMENTS / "maps" / "rooms_01.toml", ["smoothing.enabled=false", "simulation.enabled=false"])
    result = mrfswarm.plan(cfg, progress=False)
    return RecedingHorizon(result.discrete.paths, result.scenario.grid, cfg.smoothing, cfg.scenario.robot_radius,
                           workers=1)


def test_a_window_tries_its_fast_durations_a_little_longer_before_the_bold_ones(monkeypatch):
    """The rooms' first window is infeasible at its fast durations; the bold ones (half the fast acceleration)
    fly its first steps longer than the fast ones do 10 % longer."""
    unled(monkeypatch)
    rh = _rooms()
    plan = rh.run()
    first = plan.windows[0]
    assert plan.certificate.ok and first.failed[0].split("pieces, ")[-1].startswith("fast:")  # fast failed
    names = [f"fast x{f:g}" for f in rh_mod.FAST_SLOWER]
    assert first.attempt in names
    factor = rh_mod.FAST_SLOWER[names.index(first.attempt)]
    fast, bold = profile(rh, "fast", first.a, first.b), profile(rh, "nominal", first.a, first.b)
    flown = first.c - first.a
    np.testing.assert_allclose(first.durations, np.concatenate([fast[:flown] * factor, bold[flown:]]))
    monkeypatch.setattr(rh_mod, "FAST_SLOWER", ())
    before = _rooms().run()
    assert before.windows[0].attempt not in names
    assert plan.makespan_s < before.makespan_s - 0.1


def test_a_window_tries_its_fast_attempt_with_the_first_step_as_planned(monkeypatch):
    """The trap of the flight-quality bench: its second window starts in the state the first one left (flown at
    the moderate profile), which the fast attempt's first step does not fit. The fast attempt with that step as
    the first window planned it flies, before the slower attempts: 25.90 s against 25.99 without it."""
    import sys

    sys.path.insert(0, str(EXPERIMENTS / "bench"))
    from flight_quality import case_config

    from mrfswarm.config import apply_overrides

    data, base = case_config("trap")
    cfg = from_dict(apply_overrides(data, ["simulation.enabled=false", "mrf.contested=downhill",
                                           "mrf.straighten=false"]), base)  # its plan
    flight = mrfswarm.plan(cfg, progress=False).continuous
    assert flight.certificate.ok
    windows = flight.windows
    followed = [k for k, w in enumerate(windows) if w.attempt.endswith(rh_mod.FOLLOWED)]
    assert followed, "no window flew the fast attempt with its first step as planned: not covered"
    for k in followed:
        w, before = windows[k], windows[k - 1]
        assert w.durations[0] == before.durations[w.a - before.a]
        assert w.failed and w.failed[0].split("pieces, ")[-1].split(":")[0].split(" with")[0] == "fast"
    # without it (the attempt inserted as the fast one itself) the window flies a slower attempt
    unfollowed(monkeypatch)
    without = mrfswarm.plan(cfg, progress=False).continuous
    assert not any(w.attempt.endswith(rh_mod.FOLLOWED) for w in without.windows)
    assert flight.makespan_s < without.makespan_s - 0.05
