"""A hopeful attempt tries its plain durations before its creep rows and holds once they have failed more often
than not (``PLAIN_FAIL_WEIGHT``): both only add rows, so a window with no solution without them has none with
them, and the variants are not solved. That is exact for an infeasible window; a hopeful attempt's solve can also
fail for its iteration budget, and the lazy rows the plain solve adds change later solves, so a window can end
with another attempt: the flight stays within a fraction of a percent.

The 40 robots in clutter of the flight-quality bench: their windows' fast attempts have no solution in most
windows, with or without the creep rows.
"""

from __future__ import annotations

import sys

import numpy as np
import pytest

import mrfswarm.continuous.receding_horizon as rhm
from mrfswarm.config import apply_overrides, from_dict
from mrfswarm.continuous.receding_horizon import RecedingHorizon
from mrfswarm.pipeline import plan, qp_options
from support.repository import EXPERIMENTS

_SOLVE = RecedingHorizon._solve  # unwrapped: each flight counts its own solves


@pytest.fixture(scope="module")
def clutter():
    sys.path.insert(0, str(EXPERIMENTS / "bench"))
    from flight_quality import case_config

    data, base = case_config("clutter40")
    # the plan of the "downhill" rule, whose windows these tests were written on
    cfg = from_dict(apply_overrides(data, ["simulation.enabled=false", "smoothing.enabled=false",
                                           "mrf.contested=downhill"]), base)
    return cfg, plan(cfg, progress=False)


def _flight(monkeypatch, clutter, weight: float):
    cfg, discrete = clutter
    monkeypatch.setattr(rhm, "PLAIN_FAIL_WEIGHT", weight)
    calls = []
    solve = _SOLVE

    def counted(self, *args, **kwargs):
        calls.append(kwargs.get("creep") is not None or kwargs.get("hold", False))
        return solve(self, *args, **kwargs)

    monkeypatch.setattr(RecedingHorizon, "_solve", counted)
    rh = RecedingHorizon(discrete.discrete.paths, discrete.scenario.grid, cfg.smoothing, cfg.scenario.robot_radius,
                         cfg.smoothing.backend, qp_options(cfg), workers=1)
    if weight == np.inf:
        rh.plain_odds[0] = 1  # the plain durations first from the first window on
    return rh.run(), rh, calls


def test_the_plain_durations_first_fly_the_plan_as_soon_with_fewer_solves(monkeypatch, clutter):
    soft_first, rh_soft, soft_calls = _flight(monkeypatch, clutter, 0.0)  # never first: the order before
    plain_first, rh_plain, plain_calls = _flight(monkeypatch, clutter, np.inf)  # always first
    assert rh_soft.plain_odds[0] > 0, "no attempt failed without its creep rows: the test no longer covers it"
    assert plain_first.certificate.ok and len(plain_first.windows) == len(soft_first.windows)
    assert plain_first.makespan_s == pytest.approx(soft_first.makespan_s, rel=0.01)
    same = sum(p.attempt == s.attempt and p.creep == s.creep for p, s in zip(plain_first.windows, soft_first.windows))
    assert same >= 0.75 * len(soft_first.windows)
    # the attempts without a solution were solved once, not once per variant
    assert sum(plain_calls) < sum(soft_calls) and len(plain_calls) < len(soft_calls)
    skipped = [f for w in plain_first.windows for f in w.failed if "with creep rows" in f]
    assert len(skipped) < len([f for w in soft_first.windows for f in w.failed if "with creep rows" in f])


def test_the_odds_decide_the_order(monkeypatch, clutter):
    """With the default weight the run starts with the creep rows (no odds yet) and turns to the plain durations
    once they failed more often than they were solved: some soft variants of failing attempts are skipped."""
    weight = rhm.PLAIN_FAIL_WEIGHT
    default, rh, calls = _flight(monkeypatch, clutter, weight)
    never, rh_never, never_calls = _flight(monkeypatch, clutter, 0.0)
    fails, solved = rh.plain_odds
    assert fails * weight > solved  # clutter: the plain order pays, and was taken
    assert sum(calls) < sum(never_calls)
    assert default.certificate.ok and default.makespan_s == pytest.approx(never.makespan_s, rel=0.01)
