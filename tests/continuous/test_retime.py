"""The whole flight re-timed (``RecedingHorizon._retime``): a flight of at most ``RETIME_HORIZONS`` horizons' steps is
planned once more as one window at its flown durations times a factor, and the last certified factor is flown."""

from __future__ import annotations

import dataclasses
import sys

import numpy as np
import pytest

import mrfswarm.continuous.receding_horizon as rhm
from mrfswarm.config import apply_overrides, from_dict
from mrfswarm.continuous.certificate import Certificate
from mrfswarm.continuous.receding_horizon import RecedingHorizon
from mrfswarm.pipeline import plan, qp_options
from support.repository import EXPERIMENTS


@pytest.fixture(scope="module")
def arena():
    """The flight-quality bench's arena (8 robots, 0.25 m cells, v_max 1, 16 steps): its discrete plan and config."""
    sys.path.insert(0, str(EXPERIMENTS / "bench"))
    from flight_quality import case_config

    data, base = case_config("arena8")
    cfg = from_dict(apply_overrides(data, ["simulation.enabled=false", "smoothing.enabled=false"]), base)
    return plan(cfg, progress=False), cfg


def _fly(arena, retime: bool, monkeypatch, **smoothing) -> rhm.ContinuousPlan:
    discrete, cfg = arena
    monkeypatch.setattr(rhm, "RETIME_HORIZONS", 2 if retime else 0)
    sm = dataclasses.replace(cfg.smoothing, **smoothing)
    return RecedingHorizon(discrete.discrete.paths, discrete.scenario.grid, sm, cfg.scenario.robot_radius,
                           cfg.smoothing.backend, qp_options(cfg), workers=1).run()


@pytest.mark.parametrize("refined", [False, True])
def test_a_short_flight_is_re_timed_sooner_and_certified(arena, monkeypatch, refined):
    """The arena, 16 steps in windows of 8 flying 4: default 5.78 -> 5.43 s (x0.94), refined 5.48 -> 5.37 (x0.98);
    the same start and end, one piece per step, every step the same factor shorter."""
    before = _fly(arena, False, monkeypatch, time_refinement=refined)
    after = _fly(arena, True, monkeypatch, time_refinement=refined)
    assert before.retimed is None and after.retimed is not None and after.retimed < 1
    assert after.makespan_s == pytest.approx(before.makespan_s * after.retimed, rel=1e-12)
    assert after.makespan_s < before.makespan_s * 0.985
    np.testing.assert_allclose(np.diff(after.knot_times), np.diff(before.knot_times) * after.retimed, rtol=1e-12)
    assert after.certificate.ok and after.v_max <= arena[1].smoothing.v_max + 1e-9
    for a, b in zip(before.trajectories, after.trajectories):
        np.testing.assert_allclose(a(0.0), b(0.0), atol=1e-9)
        np.testing.assert_allclose(a(a.duration), b(b.duration), atol=1e-6)
        assert a.pieces == b.pieces


def test_an_uncertified_re_timing_is_not_flown(arena, monkeypatch):
    """Every whole-flight solution rejected by the certificate: the windows' flight is flown, unchanged."""
    before = _fly(arena, False, monkeypatch)
    certify = RecedingHorizon._certify

    def reject_whole_flight(self, sol, a):
        if a == 0 and len(sol.durations) == self.T:
            return Certificate(ok=False, problems=["rejected by the test"])
        return certify(self, sol, a)

    monkeypatch.setattr(RecedingHorizon, "_certify", reject_whole_flight)
    after = _fly(arena, True, monkeypatch)
    assert after.retimed is None
    np.testing.assert_array_equal(after.knot_times, before.knot_times)
    for a, b in zip(before.trajectories, after.trajectories):
        np.testing.assert_array_equal(a.coefficients, b.coefficients)


def test_rest_seams_a_cruise_speed_and_long_flights_are_not_re_timed(arena, monkeypatch):
    """The paper's rest-to-rest seams stay as they are, and so does a user's cruise ``speed``; a flight longer than
    RETIME_HORIZONS horizons is not re-timed (the arena at a horizon of 6: 16 steps > 12)."""
    assert _fly(arena, True, monkeypatch, seam="rest").retimed is None
    assert _fly(arena, True, monkeypatch, speed=0.8).retimed is None
    assert _fly(arena, True, monkeypatch, horizon=6).retimed is None


def test_a_re_timed_flight_keeps_its_arrived_robots_held(monkeypatch):
    """The whole flight's QP keeps the windows' holds: robot 0 of tests/continuous/test_hold.py's flight (16 steps,
    arrived at step 6) stays at its cell, to the QP's tolerance on the equality rows (5e-9 to 4e-8 measured, where a
    window's QP met them to 1e-11), and the flight is re-timed sooner."""
    sys.path.insert(0, str(EXPERIMENTS.parent / "tests" / "continuous"))
    import test_hold

    monkeypatch.setattr(rhm, "RETIME_HORIZONS", 0)
    windows = test_hold._flight(monkeypatch, True)  # its ladder as the hold tests take it
    monkeypatch.setattr(rhm, "RETIME_HORIZONS", 2)
    after = test_hold._flight(monkeypatch, True)
    assert after.retimed is not None and after.makespan_s < windows.makespan_s and after.certificate.ok
    assert any(w.hold for w in after.windows)
    v, off = test_hold._after_arrival(after)
    assert v.max() < 1e-6 and off.max() < 1e-6
