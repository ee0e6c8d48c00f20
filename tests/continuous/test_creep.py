"""A robot that waits a few steps between two moves the same way drifts through its cell instead of stopping.

Robot 0 flies east along y = 1, waits five steps (a run ``CREEP_WAITS`` = 8 lets creep) at x = 4, and
flies on; robot 1 zigzags east along y = 4 and 5 throughout (a turn every step: the steps are
slow). With half a cell of region growth the wait leaves robot 0 about a metre of room. The
wait is a run of :func:`~mrfswarm.continuous.time_grid.drift_waits`: the window QP keeps robot
0 moving east at ``CREEP_SPEED`` or faster through it (rows on its velocity control points);
without those rows it stops there (measured: down to 0.001 m/s, two stops; 11.97 s either way).
"""

from __future__ import annotations

import numpy as np
import pytest

import mrfswarm.continuous.receding_horizon as rhm
from mrfswarm.config import SmoothingConfig
from mrfswarm.continuous.receding_horizon import CREEP_SPEED, CREEP_WAITS, RecedingHorizon
from mrfswarm.continuous.time_grid import drift_waits
from mrfswarm.flight_quality import count_stops
from mrfswarm.maps import OccupancyGrid
from support.attempts import unled

WAITS = 5  # eight at 0.1 m/s would need more than the metre of room its cell leaves it, at these slow steps
ROBOT0 = [(x, 1) for x in range(5)] + [(4, 1)] * WAITS + [(x, 1) for x in range(5, 10)]
PATHS = np.array([[a, (i, 4 + i % 2)] for i, a in enumerate(ROBOT0)])
GRID = OccupancyGrid.from_occupied(np.zeros((20, 8), bool))
WAIT = slice(4, 4 + WAITS)


def _flight(creep_speed: float, monkeypatch) -> tuple[RecedingHorizon, object]:
    monkeypatch.setattr(rhm, "CREEP_SPEED", creep_speed)
    unled(monkeypatch)  # the creep rows alone (leading, the robot starts its move in the wait: no stop without them)
    rh = RecedingHorizon(PATHS, GRID, SmoothingConfig(max_pieces=0, region_growth=0.5), 0.25, workers=1)
    return rh, rh.run()


def _wait_speeds(plan) -> np.ndarray:
    """Robot 0's speed sampled through its waiting steps."""
    knots = plan.knot_times
    assert len(knots) == len(PATHS)  # one piece per step
    t = np.linspace(knots[WAIT.start], knots[WAIT.stop], 400)
    return np.linalg.norm(plan.trajectories[0].evaluate(t, 1), axis=-1)


def test_the_waits_are_a_drifting_run():
    waits, way, runs = drift_waits(np.diff(PATHS, axis=0).astype(float), CREEP_WAITS)
    assert waits[:, 0].tolist() == [False] * 4 + [True] * WAITS + [False] * 5
    np.testing.assert_allclose(way[WAIT, 0], [[1.0, 0.0]] * WAITS)
    assert runs[WAIT, 0].tolist() == [WAITS] * WAITS and not waits[:, 1].any()


def test_a_short_wait_is_flown_as_a_drift_not_a_stop(monkeypatch):
    rh, plan = _flight(CREEP_SPEED, monkeypatch)
    assert plan.certificate.ok
    assert any(w.creep for w in plan.windows)
    v = _wait_speeds(plan)
    assert v.min() >= CREEP_SPEED * (1 - 1e-6)
    e = plan.trajectories[0].evaluate(np.linspace(plan.knot_times[WAIT.start], plan.knot_times[WAIT.stop], 50), 1)[:, 0]
    assert np.all(e > 0)  # along its way: east
    assert count_stops(plan.trajectories).per_robot.tolist() == [0, 0]


def test_without_the_rows_the_robot_stops(monkeypatch):
    """The control: the same plan without the creep rows stops robot 0 in its wait."""
    _, plan = _flight(0.0, monkeypatch)
    assert not any(w.creep for w in plan.windows)
    assert _wait_speeds(plan).min() < 0.05
    assert count_stops(plan.trajectories).per_robot[0] >= 1


@pytest.mark.parametrize("waits, drifting", [(CREEP_WAITS, True), (CREEP_WAITS + 1, False)])
def test_only_runs_up_to_the_cap_drift(waits, drifting):
    xs = [0, 1, 2] + [2] * waits + [3, 4]
    moves = np.diff(np.array([[[x, 0]] for x in xs], dtype=float), axis=0)
    assert drift_waits(moves, CREEP_WAITS)[0][:, 0].any() == drifting


def test_a_wait_before_a_turn_of_90_degrees_or_more_does_not_drift():
    cells = [(0, 0), (1, 0), (2, 0), (2, 0), (2, 1), (2, 2)]  # east, wait, north
    moves = np.diff(np.array([[c] for c in cells], dtype=float), axis=0)
    assert not drift_waits(moves, CREEP_WAITS)[0].any()


def test_where_the_rows_cannot_be_met_the_same_durations_are_flown_without_them(monkeypatch):
    """Creep rows no flight can meet (faster than v_max): every drifting attempt fails with them and is then
    flown without them, so the windows fly what they fly without the rows at all."""
    _, free = _flight(0.0, monkeypatch)
    _, blocked = _flight(10.0, monkeypatch)
    assert [w.attempt for w in blocked.windows] == [w.attempt for w in free.windows]
    assert not any(w.creep for w in blocked.windows)
    assert any("with creep rows" in f for w in blocked.windows for f in w.failed)
    np.testing.assert_allclose(blocked.knot_times, free.knot_times)
