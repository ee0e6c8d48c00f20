"""The stretched attempts of a window (RecedingHorizon._stretched): the first profile's durations, longer where the
limits ask."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

import mrfswarm
import mrfswarm.continuous.receding_horizon as rh_mod
from mrfswarm.config import SmoothingConfig, apply_overrides, from_dict
from mrfswarm.continuous.formulation import LIMIT_ORDERS, limit_polytope
from mrfswarm.continuous.receding_horizon import RecedingHorizon, WindowRecord
from support.passing import GRID, PASSING, first_window

MAPS = Path(__file__).parents[2] / "experiments" / "maps"


def passing(**limits) -> RecedingHorizon:
    return RecedingHorizon(PASSING, GRID, SmoothingConfig(**limits), 0.25, workers=1)


def bold(rh: RecedingHorizon, a: int, b: int) -> np.ndarray:
    """The bold profile's durations of window a..b."""
    return rh.profiles[[name for name, _, _ in rh_mod.PROFILES].index("nominal")].window(a, b)


def peaks(rh: RecedingHorizon, sol) -> np.ndarray:
    """(3, M) the largest r-th derivative control point of any robot in each step over its limit row (faces)."""
    faces, inner = limit_polytope(rh.dim)
    return np.array([np.abs(sol.cps[r] @ faces.T).max(axis=(0, 2, 3)) / (lim * inner)
                     for r, lim in zip(LIMIT_ORDERS, rh.row_limits)])


def test_the_stretch_flies_a_window_whose_durations_are_too_short():
    """Half the bold durations break the limits; stretched by the solution without limit rows, the window solves
    and certifies, each step no shorter than before and the half stretch the geometric mean."""
    rh = passing(j_max=3.0)
    a, c, b, start, rec = first_window(rh)
    short = 0.5 * bold(rh, a, b)
    assert rh._solve(a, b, start, short, WindowRecord(a, c, b))[0] is None
    rows = rh.limit_rows.copy()
    assert rows[a:b].any()  # the failed solve switched some on
    out = rh._stretched(a, c, b, start, short, np.full(b - a, 1e3), rec, None, None)
    assert [name for name, _ in out] == ["stretched^0.5", "stretched^1"]
    half, full = out[0][1], out[1][1]
    assert np.all(full >= short) and full.sum() > 1.2 * short.sum()
    assert half == pytest.approx(np.sqrt(short * full))
    np.testing.assert_array_equal(rh.limit_rows, rows)  # the probe leaves the lazy limit rows as they were
    sol, why = rh._solve(a, b, start, full, WindowRecord(a, c, b))
    assert sol is not None, why
    assert rh._certify(sol, a).ok
    # each step stretched by what the solution without limit rows at the short durations asks (the exponent 1/r:
    # a piece flown s times slower has r-th derivatives s^r times smaller)
    rh.limit_rows[a:b] = False
    free, _ = rh._solve(a, b, start, short, WindowRecord(a, c, b), limits=False)
    over = peaks(rh, free)
    assert over.max() > 1.5  # the short durations break the limits by far
    need = np.maximum(1.0, (over ** (1.0 / np.array(LIMIT_ORDERS))[:, None]).max(axis=0))
    assert full == pytest.approx(short * need, rel=1e-5)  # (and the margin of 1e-6)


def test_no_stretch_slower_than_the_cautious_profile():
    rh = passing(j_max=3.0)
    a, c, b, start, rec = first_window(rh)
    short = 0.5 * bold(rh, a, b)
    assert rh._stretched(a, c, b, start, short, short, rec, None, None) == []


def test_a_probe_without_solution_adds_no_attempt(monkeypatch):
    rh = passing(j_max=3.0)
    a, c, b, start, rec = first_window(rh)
    monkeypatch.setattr(rh_mod, "solve_window", lambda *args, **kwargs: "no solution here")
    short = 0.5 * bold(rh, a, b)
    assert rh._stretched(a, c, b, start, short, np.full(b - a, 1e3), rec, None, None) == []
    assert rec.failed == ["stretch: 2 robots: no solution here"]


@pytest.fixture(scope="module")
def forest():
    """The first window of a 10-robot forest, with the fast, the bold and the moderate profiles rash (cruise at 1.5
    v_max, 4 times their acceleration): none of them has a solution there. (At their own the default flies the
    window fast since the windows' stops keep to the jerk limit: time_grid.rest_times.)"""
    data = tomllib.loads((MAPS / "forest_01.toml").read_text())
    data["scenario"]["start"].update(n_robots=10, sigma=1.5)
    data["interaction"]["k"] = 7
    cfg = from_dict(apply_overrides(data, ["smoothing.enabled=false", "simulation.enabled=false"]), MAPS)
    result = mrfswarm.plan(cfg, progress=False)
    rash = tuple((name, cruise, acc) if name == "cautious" else (name, 1.5, 4 * acc) for name, cruise, acc in
                 rh_mod.PROFILES)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(rh_mod, "PROFILES", rash)
        rh = RecedingHorizon(result.discrete.paths, result.scenario.grid, cfg.smoothing, cfg.scenario.robot_radius,
                             workers=1)
    return rh, first_window(rh)


def test_a_forest_window_flies_the_stretch_sooner_than_the_cautious_profile(forest, monkeypatch):
    rh, (a, c, b, start, _) = forest
    # the first window also tries the jerk-limited start (its floor keeps its steps to v_max where these profiles
    # are rash, and it flies): not what this test is about
    monkeypatch.setattr(rh, "_jerk_start", lambda attempts, *args: attempts)
    monkeypatch.setattr(rh, "leading", None)  # nor the leading attempt
    sol, rec = rh._plan_window(a, c, b, start, None)
    names = [f.split(":")[0].split(", ")[-1] for f in rec.failed]
    assert names[:3] == ["fast", "nominal", "moderate"], rec.failed
    assert rec.attempt.startswith("stretched")
    cautious = rh.profiles[-1].window(a, b)
    assert sol.durations[:c - a].sum() < cautious[:c - a].sum() - 0.1
    assert rh._certify(sol, a).ok
