"""The bisection between a refined window's attempts (``RecedingHorizon._bisect``): where the window fits between two
rungs of its ladder, it flies durations between them, and only certified ones; the default does not bisect."""

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


def _flight(refined: bool = True) -> rhm.ContinuousPlan:
    """The flight of the flight-quality bench's trap (5 robots out of a U-shaped trap, 38 steps)."""
    sys.path.insert(0, str(EXPERIMENTS / "bench"))
    from flight_quality import case_config

    data, base = case_config("trap")
    cfg = from_dict(apply_overrides(data, ["simulation.enabled=false", "smoothing.enabled=false"]), base)
    discrete = plan(cfg, progress=False)
    sm = dataclasses.replace(cfg.smoothing, time_refinement=refined)
    return RecedingHorizon(discrete.discrete.paths, discrete.scenario.grid, sm, cfg.scenario.robot_radius,
                           cfg.smoothing.backend, qp_options(cfg), workers=1).run()


def _spied(monkeypatch) -> list[tuple]:
    """Every call of the bisection: (the certified durations, the failed faster ones it goes towards, the result's)."""
    calls: list[tuple] = []
    bisect = RecedingHorizon._bisect

    def spy(self, a, c, b, start, chosen, missed, rec, merged):
        out = bisect(self, a, c, b, start, chosen, missed, rec, merged)
        faster = [d for d in missed if d[:c - a].sum() < chosen.durations[:c - a].sum()]
        calls.append((c - a, chosen.durations, faster[-1] if faster else None, out.durations, rec))
        return out

    monkeypatch.setattr(RecedingHorizon, "_bisect", spy)
    return calls


def test_a_refined_window_flies_between_its_rungs(monkeypatch):
    """The refined trap: windows whose faster attempts have no solution fly durations between those and the attempt
    they flew, certified, and the flight is sooner (24.76 -> 24.62 s)."""
    assert rhm.BISECTIONS >= 1
    calls = _spied(monkeypatch)
    flight = _flight()
    kept = [(flown, ok, bad, out, rec) for flown, ok, bad, out, rec in calls if rec.bisected]
    assert kept, "no window was bisected: the test no longer covers it"
    for flown, ok, bad, out, rec in kept:
        assert bad is not None and bad[:flown].sum() < out[:flown].sum() < ok[:flown].sum()
        # the geometric means of the certified durations and the failed ones, rec.bisected times towards the latter
        assert np.all(np.minimum(ok, bad) - 1e-12 <= out) and np.all(out <= np.maximum(ok, bad) + 1e-12)
        assert rec.bisected <= rhm.BISECTIONS
    assert flight.certificate.ok and flight.min_separation >= 0
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(rhm, "BISECTIONS", 0)
        ladder = _flight()
    assert all(w.bisected == 0 for w in ladder.windows)
    assert flight.makespan_s < ladder.makespan_s - 0.05


def test_the_default_does_not_bisect(monkeypatch):
    """Bisecting every window (twice) cost the default's planning of big swarms 50-60 % (200 robots in clutter 111 -> 163 s,
    the 1000-robot crossing 241 -> 392 s) for 2 % and 0.1 % of their flights."""
    calls = _spied(monkeypatch)
    flight = _flight(refined=False)
    assert flight.certificate.ok
    assert calls and not any(rec.bisected for *_, rec in calls)
    assert any(bad is not None for _, _, bad, _, _ in calls)  # a window had a faster attempt that failed


def test_an_uncertified_point_is_not_flown(monkeypatch):
    """A bisection point whose certificate fails is a rung not reached: the window flies its attempt."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(rhm, "BISECTIONS", 0)
        ladder = _flight()
    bisect, certify = RecedingHorizon._bisect, RecedingHorizon._certify
    inside: list[bool] = []

    def bisect_spy(self, *args, **kwargs):
        inside.append(True)
        try:
            return bisect(self, *args, **kwargs)
        finally:
            inside.pop()

    def certify_spy(self, sol, a):
        cert = certify(self, sol, a)
        return Certificate(ok=False, problems=["made to fail"]) if inside and cert.ok else cert

    monkeypatch.setattr(RecedingHorizon, "_bisect", bisect_spy)
    monkeypatch.setattr(RecedingHorizon, "_certify", certify_spy)
    flight = _flight()
    assert [w.bisected for w in flight.windows] == [0] * len(flight.windows)
    assert flight.makespan_s == pytest.approx(ladder.makespan_s, rel=1e-9)
    assert flight.certificate.ok
