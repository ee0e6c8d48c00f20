"""The leading attempt: robots ahead of or behind their cells at a window's inner knots
(time_grid.lead_needs, receding_horizon.LEADING)."""

from __future__ import annotations

import itertools
import sys
from dataclasses import replace

import numpy as np
import pytest

import mrfswarm
import mrfswarm.continuous.receding_horizon as rh_mod
from mrfswarm.config import apply_overrides, from_dict
from mrfswarm.continuous.receding_horizon import RecedingHorizon
from mrfswarm.continuous.time_grid import lead_needs
from support.attempts import unretimed
from support.repository import EXPERIMENTS


def knot_slack(T: int, s: float) -> np.ndarray:
    out = np.full(T + 1, s)
    out[0] = out[-1] = 0.0
    return out


def test_without_slack_a_step_lasts_its_slowest_mover_s_need():
    needs = np.random.default_rng(0).uniform(0.0, 1.0, (12, 5))
    np.testing.assert_allclose(lead_needs(needs, 0.0), needs.max(axis=1), atol=1e-12)


@pytest.mark.parametrize("seed", range(4))
def test_every_robot_flies_every_stretch_within_its_slack_and_no_knot_could_come_sooner(seed):
    rng = np.random.default_rng(seed)
    T, N = 15, 6
    needs = rng.uniform(0.0, 1.0, (T, N)) * (rng.uniform(size=(T, N)) > 0.2)  # some waits
    slack = rng.uniform(0.0, 0.3, T + 1)
    tau = np.concatenate([[0.0], np.cumsum(lead_needs(needs, slack))])
    C = np.concatenate([np.zeros((1, N)), np.cumsum(needs, axis=0)])
    assert np.all(np.diff(tau) >= 0)
    for a, b in itertools.combinations(range(T + 1), 2):  # tau_b - tau_a >= C_b - C_a - s_a - s_b
        assert np.all(tau[b] - tau[a] >= C[b] - C[a] - slack[a] - slack[b] - 1e-12)
    # the earliest: every knot is as late as the knot before or as one stretch asks, no later
    for b in range(1, T + 1):
        asks = max((C[b] - C[a] - slack[a] - slack[b] + tau[a]).max() for a in range(b))
        assert tau[b] == pytest.approx(max(tau[b - 1], asks), abs=1e-12)


def test_a_diagonal_merge_into_a_file_borrows_time_from_the_steps_around_it():
    # a file at 0.5 s per cell; a robot waiting beside it (need 0) merges diagonally (0.71 s) in step 3, then
    # follows the file
    needs = np.array([[0.5, 0.0]] * 3 + [[0.5, 0.71]] + [[0.5, 0.5]] * 3)
    plain = needs.max(axis=1)
    leading = lead_needs(needs, knot_slack(7, 0.12))
    assert plain.sum() == pytest.approx(3.71)
    assert leading.sum() == pytest.approx(3.5)  # the file's own pace: the merge starts in the wait before it
    assert leading[3] < 0.71


def test_a_slack_of_the_wrong_length_is_refused():
    with pytest.raises(ValueError, match="one per knot"):
        lead_needs(np.ones((4, 2)), np.zeros(4))


@pytest.fixture(scope="module")
def corridor():
    """The flight-quality bench's corridor (the paper's, 5 robots): the config and its discrete plan."""
    sys.path.insert(0, str(EXPERIMENTS / "bench"))
    import flight_quality as fq

    data, base = fq.case_config("corridor")
    cfg = from_dict(apply_overrides(data, ["simulation.enabled=false"]), base)
    plan = mrfswarm.plan(replace(cfg, smoothing=replace(cfg.smoothing, enabled=False)), progress=False)
    return cfg, plan


def horizon(corridor) -> RecedingHorizon:
    cfg, plan = corridor
    return RecedingHorizon(plan.discrete.paths, plan.scenario.grid, cfg.smoothing, cfg.scenario.robot_radius,
                           workers=1)


def test_the_corridor_flies_sooner_leading_and_stays_certified(corridor, monkeypatch):
    unretimed(monkeypatch)
    led = horizon(corridor).run()
    assert led.certificate.ok
    assert sum(w.attempt.startswith(rh_mod.LEADING) for w in led.windows) >= 3
    monkeypatch.setattr(rh_mod, "LEAD_ROOM", 0.0)
    rh = horizon(corridor)
    assert rh.leading is None
    plain = rh.run()
    assert not any(w.attempt.startswith(rh_mod.LEADING) for w in plain.windows)
    assert led.makespan_s < plain.makespan_s - 0.5  # 20.5 s -> 19.5


def test_the_leading_attempt_comes_first_and_only_where_it_is_sooner(corridor):
    rh = horizon(corridor)
    for a, c, b in rh.windows():
        attempts = rh._profile_attempts(a, c, b)
        names = [n for n, _ in attempts]
        if names[0] == rh_mod.LEADING:
            durations = dict(attempts)
            assert durations[rh_mod.LEADING][:c - a].sum() < durations["fast"][:c - a].sum()
            # its tail, planned and not flown, brakes as the bold profile
            np.testing.assert_array_equal(durations[rh_mod.LEADING][c - a:], durations["nominal"][c - a:])
        else:
            assert rh_mod.LEADING not in names


def test_a_failed_leading_attempt_leaves_the_rows_as_they_were(corridor, monkeypatch):
    """A leading attempt that no QP can meet (every step a tenth of the fast one's) switches on rows in its rounds
    before it fails; the window then goes on from the rows it had, so the flight is the one without it, row for
    row."""
    unretimed(monkeypatch)
    monkeypatch.setattr(rh_mod, "LEAD_ROOM", 0.0)
    plain = horizon(corridor)
    flight = plain.run()
    attempts = RecedingHorizon._profile_attempts

    def hopeless(self, a, c, b):
        out = attempts(self, a, c, b)
        return [(rh_mod.LEADING, dict(out)["fast"] * 0.1), *out]

    monkeypatch.setattr(RecedingHorizon, "_profile_attempts", hopeless)
    rh = horizon(corridor)
    failed = rh.run()
    assert all(w.failed and rh_mod.LEADING in w.failed[0] for w in failed.windows), [w.failed[:1] for w in failed.windows]
    np.testing.assert_array_equal(rh.active, plain.active)
    np.testing.assert_array_equal(rh.limit_rows, plain.limit_rows)
    assert [w.attempt for w in failed.windows] == [w.attempt for w in flight.windows]
    np.testing.assert_array_equal(failed.knot_times, flight.knot_times)
