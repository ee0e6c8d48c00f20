"""A QP backend that gives no multipliers leaves the time refinement without its gradient: one warning says so (a
tour's backend refined nothing and flew later than the default, without a word)."""

from __future__ import annotations

import logging

import mrfswarm.continuous.receding_horizon as rhm
from mrfswarm.config import load_config
from mrfswarm.pipeline import plan
from support.repository import EXPERIMENTS


def _refined(monkeypatch, without: bool):
    if without:
        solve = rhm.solve_window

        def no_multipliers(*args, **kwargs):
            out = solve(*args, **kwargs)
            return out if isinstance(out, str) else (*out[:3], None)

        monkeypatch.setattr(rhm, "solve_window", no_multipliers)
    # not free5: its one window "refined" was its QP's durations but for rounding (2e-16 s), not a refinement
    cfg = load_config(EXPERIMENTS / "single_obstacle.toml", ["simulation.enabled=false", "smoothing.time_refinement=true"])
    return plan(cfg, progress=False, workers=1).continuous


def test_a_backend_without_multipliers_is_said_once(monkeypatch, caplog):
    with caplog.at_level(logging.WARNING, logger="mrfswarm.continuous.receding_horizon"):
        with_gradient = _refined(monkeypatch, False)
    assert "no multipliers" not in caplog.text and any(w.refined for w in with_gradient.windows)
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="mrfswarm.continuous.receding_horizon"):
        flight = _refined(monkeypatch, True)
    said = [r for r in caplog.records if "gives no multipliers" in r.getMessage()]
    assert len(said) == 1 and "QP backend piqp gives no multipliers" in said[0].getMessage()
    assert not any(w.refined for w in flight.windows) and flight.certificate.ok
