"""A refined window whose next window misses its fast profile is planned again unrefined.

The time refinement shortens one window at a time (``RecedingHorizon._refine``); it can leave the
swarm in a state the next window's profiles cannot take over from, which then flies a slower profile
or the previous window's braking tail. ``RecedingHorizon._undo_refinement`` plans that next window
again from the unrefined solution and keeps the pair that flies sooner.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from mrfswarm.config import load_config
from mrfswarm.continuous.receding_horizon import RecedingHorizon
from mrfswarm.pipeline import plan
from support.attempts import unbisected, unfollowed, unretimed
from support.repository import EXPERIMENTS

# the forests of experiments/bench/flight_quality.py: 10 robots, k = 7
#: The plans of the "downhill" contested rule, on which the undo was needed.
FOREST = ("scenario.start.n_robots=10", "scenario.start.sigma=1.5", "interaction.k=7", "simulation.enabled=false",
          "mrf.contested=downhill", "mrf.straighten=false")


def old_attempts(monkeypatch) -> None:
    """Every window refined and its attempts with the profiles' own first step, as when the undo was needed:
    since the windows whose flown steps the scaling would only lengthen are kept unrefined
    (``RecedingHorizon._shortens_flown``) and the attempts after a window fly its planned first step
    (``RecedingHorizon._follow``), neither the forest's nor window3d's refined flight needs one."""
    monkeypatch.setattr(RecedingHorizon, "_shortens_flown", lambda self, sol, rec: True)
    unfollowed(monkeypatch)


def test_a_refinement_the_next_window_cannot_follow_is_undone(monkeypatch):
    """On forest_04 (10 robots, the default weight) four refined windows left the next one only the previous
    window's braking tail: refined, the flight took 28.71 s against 28.47 unrefined; with the undo, window 4..12
    planned again from window 0..8 unrefined flies the stretched bold durations, and the flight 27.30 s.
    (forest_01 at weight 10 showed it before the trial points started from the best point's rows: 26.3 s against
    26.1 unrefined, 24.8 undone.)"""
    old_attempts(monkeypatch)
    path: Path = EXPERIMENTS / "maps" / "forest_04.toml"
    default = plan(load_config(path, list(FOREST)), progress=False).continuous
    refined = plan(load_config(path, [*FOREST, "smoothing.time_refinement=true"]), progress=False).continuous
    undone = [w for w in refined.windows if any(f.startswith("after window") for f in w.failed)]
    assert undone, "the undo did not fire: the test no longer covers it"
    assert not any(w.attempt == "previous" for w in undone)
    assert refined.certificate.ok
    assert refined.makespan_s < 0.97 * default.makespan_s


@pytest.mark.parametrize("attempts", ["old", "now"])
def test_refining_window3d_flies_no_later_than_its_default(monkeypatch, attempts):
    """window3d's last window missed the fast profile after its refined predecessor (12.4 s against 12.0 s
    unrefined); planned again from the unrefined window it flies as the default does. Now its attempts
    follow the refined window's first step, and it needs no undo. (Its windows' flights: the whole flight, short
    enough, is re-timed after them, the default's further.)"""
    unretimed(monkeypatch)
    if attempts == "old":
        old_attempts(monkeypatch)
    path: Path = EXPERIMENTS / "window3d.toml"
    pinned = ["simulation.enabled=false", "mrf.contested=downhill", "mrf.straighten=false"]
    default = plan(load_config(path, pinned), progress=False).continuous
    refined = plan(load_config(path, [*pinned, "smoothing.time_refinement=true"]), progress=False).continuous
    undone = any(f.startswith("after window") for w in refined.windows for f in w.failed)
    assert undone == (attempts == "old")
    assert refined.certificate.ok
    assert refined.makespan_s <= default.makespan_s + 1e-9


def test_after_a_refined_window_every_attempt_flies_the_first_step_as_planned(monkeypatch):
    """A window starts in the state the window before left (speed, acceleration), which pins its first step:
    with the time refinement every attempt keeps that step's duration from the window before. On the forest
    two of nine windows fell back to the previous window's durations after a refined one, after 11 and 6
    failed attempts (664a455): now no window of it does."""
    unbisected(monkeypatch)
    attempts: list[tuple[int, float]] = []
    solve, refine = RecedingHorizon._solve, RecedingHorizon._refine
    refining = []

    def recording(self, a, b, start, durations, *args, **kwargs):
        if not refining:
            attempts.append((a, float(durations[0])))
        return solve(self, a, b, start, durations, *args, **kwargs)

    def flagged(self, *args, **kwargs):
        refining.append(True)
        try:
            return refine(self, *args, **kwargs)
        finally:
            refining.pop()

    monkeypatch.setattr(RecedingHorizon, "_solve", recording)
    monkeypatch.setattr(RecedingHorizon, "_refine", flagged)
    path: Path = EXPERIMENTS / "maps" / "forest_01.toml"
    refined = plan(load_config(path, [*FOREST, "smoothing.time_refinement=true"]), progress=False).continuous
    assert refined.certificate.ok
    windows = refined.windows
    assert sum(w.refined for w in windows) >= 2
    planned = {n.a: w.durations[n.a - w.a] for w, n in zip(windows, windows[1:])}
    tried = [(a, d) for a, d in attempts if a in planned]
    assert len({a for a, _ in tried}) == len(planned)
    for a, d in tried:
        assert d == planned[a], f"window at step {a}: an attempt's first step {d} s, planned {planned[a]} s"
    assert not any(w.attempt == "previous" for w in windows)


def test_a_window_flown_as_its_witness_leaves_nothing_to_undo(monkeypatch):
    """A window whose attempts all fail flies its witness, unrefined: the undo must not take the refined window
    before it for this one (it would commit that window's solution in this one's steps)."""
    unbisected(monkeypatch)
    solve, plan_window = RecedingHorizon._solve, RecedingHorizon._plan_window
    after_refined: list[bool] = []

    def failing(self, a, b, start, durations, *args, **kwargs):
        if a == 8:
            return None, "made to fail"
        return solve(self, a, b, start, durations, *args, **kwargs)

    def checked(self, a, c, b, *args, **kwargs):
        if a == 8:
            after_refined.append(self.unrefined is not None)
        sol, rec = plan_window(self, a, c, b, *args, **kwargs)
        if a == 8:
            assert rec.attempt == "witness" and self.unrefined is None
        return sol, rec

    monkeypatch.setattr(RecedingHorizon, "_solve", failing)
    monkeypatch.setattr(RecedingHorizon, "_plan_window", checked)
    path: Path = EXPERIMENTS / "maps" / "forest_01.toml"
    refined = plan(load_config(path, [*FOREST, "smoothing.time_refinement=true"]), progress=False).continuous
    assert after_refined[0], "the window before the witness was not refined: nothing to leave"
    assert refined.windows[2].attempt == "witness"
    assert refined.certificate.ok


def test_without_profiles_the_attempts_keep_their_own_first_step(monkeypatch):
    """With the durations of a given ``smoothing.speed`` (no profiles) the refined corridor flew 20.75 s with the
    attempts' own first step and 20.99 s following the window before's: the attempts are not followed there."""

    def never(attempts, previous):
        raise AssertionError("attempts followed without profiles")

    monkeypatch.setattr(RecedingHorizon, "_follow", staticmethod(never))
    cfg = load_config(EXPERIMENTS / "corridor.toml",
                      ["simulation.enabled=false", "smoothing.speed=1.25", "smoothing.time_refinement=true"])
    flight = plan(cfg, progress=False).continuous
    assert flight.certificate.ok and len(flight.windows) > 1 and any(w.refined for w in flight.windows)
