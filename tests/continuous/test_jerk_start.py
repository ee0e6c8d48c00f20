"""The flight's first window tries a start from rest within the jerk limit (receding_horizon.JERK_START)."""

from __future__ import annotations

import sys
from dataclasses import replace

import numpy as np
import pytest

import mrfswarm
import mrfswarm.continuous.receding_horizon as rh_mod
from mrfswarm.config import apply_overrides, from_dict
from mrfswarm.continuous.receding_horizon import RecedingHorizon
from mrfswarm.continuous.time_grid import rest_times
from support.repository import EXPERIMENTS


@pytest.fixture(scope="module")
def doorway():
    """The flight-quality bench's doorway (5 robots through a 3-cell door): the config, and the window planner of
    its discrete plan. Its first window flies neither the fast nor the bold profile."""
    sys.path.insert(0, str(EXPERIMENTS / "bench"))
    import flight_quality as fq

    data, base = fq.case_config("doorway")
    cfg = from_dict(apply_overrides(data, ["simulation.enabled=false"]), base)
    plan = mrfswarm.plan(replace(cfg, smoothing=replace(cfg.smoothing, enabled=False)), progress=False)
    return cfg, RecedingHorizon(plan.discrete.paths, plan.scenario.grid, cfg.smoothing, cfg.scenario.robot_radius,
                                workers=1)


def test_only_the_first_window_tries_it_in_order_of_its_flown_time(doorway):
    _, rh = doorway
    a, c, b = rh.windows()[0]
    attempts = rh._profile_attempts(a, c, b)
    names = [n for n, _ in attempts]
    assert names.count(rh_mod.JERK_START_NAME) == 1
    k = names.index(rh_mod.JERK_START_NAME)
    flown = [d[:c - a].sum() for _, d in attempts]
    assert k >= 1 and flown[k] < flown[k + 1]  # before the first attempt whose flown steps last longer
    assert all(f <= flown[k] for f in flown[1:k])
    # its flown steps: the fast profile's, none shorter than the jerk-limited start from rest, times the factor;
    # its tail the bold profile's
    durations = dict(attempts)
    ell = rh.profiles[[n for n, _, _ in rh_mod.PROFILES].index("fast")].ell[:c]
    floor = np.diff(np.concatenate([[0.0], rest_times(np.cumsum(ell), *rh.limits)]))
    np.testing.assert_allclose(durations[rh_mod.JERK_START_NAME][:c],
                               np.maximum(durations["fast"][:c], floor) * rh_mod.JERK_START)
    assert np.any(floor > durations["fast"][:c])  # the fast profile starts faster than the jerk limit allows
    np.testing.assert_array_equal(durations[rh_mod.JERK_START_NAME][c:], durations["nominal"][c:])
    for a2, c2, b2 in rh.windows()[1:]:
        assert rh_mod.JERK_START_NAME not in [n for n, _ in rh._profile_attempts(a2, c2, b2)]


def test_the_doorway_flies_it_and_sooner(doorway, monkeypatch):
    cfg, _ = doorway
    with_it = mrfswarm.plan(cfg, progress=False).continuous
    assert with_it is not None and with_it.certificate.ok
    first = with_it.windows[0]
    assert first.attempt == rh_mod.JERK_START_NAME
    # without it the first window falls back to a slower attempt, and the flight lasts longer
    monkeypatch.setattr(RecedingHorizon, "_jerk_start", lambda self, attempts, *args: attempts)
    without = mrfswarm.plan(cfg, progress=False).continuous
    assert without is not None
    assert without.windows[0].attempt not in ("fast", rh_mod.JERK_START_NAME)
    flown = slice(0, first.c - first.a)
    assert without.windows[0].durations[flown].sum() > first.durations[flown].sum()
    assert with_it.makespan_s < without.makespan_s
