"""A robot that has arrived for good is held still at its cell while the others fly on.

Robot 0 flies east along y = 1 for five steps and waits at x = 5 to the end of the plan;
robot 1 flies east along y = 4 for all 16 steps. Without the hold, minimum snap lets robot 0
carry its arrival speed through its grown box and back (measured: up to 0.30 m/s and 0.10 m
from its cell after step 7, one stop); held (:func:`~mrfswarm.continuous.regions.arrival_holds`),
it brakes within ``HOLD_SETTLE`` steps and stays at its cell's centre (the held box's rows are
equalities: a box a few micrometres wide left it 1.9e-5 m off and moving). The same makespan.
"""

from __future__ import annotations

import sys

import numpy as np
import pytest

import mrfswarm.continuous.receding_horizon as rhm
from mrfswarm.config import SmoothingConfig, apply_overrides, from_dict
from mrfswarm.continuous.receding_horizon import HOLD_ROOM, HOLD_SETTLE, RecedingHorizon
from mrfswarm.continuous.regions import arrival_holds
from mrfswarm.flight_quality import count_stops
from mrfswarm.maps import OccupancyGrid
from mrfswarm.pipeline import plan, qp_options
from support.attempts import unfollowed, unled, unretimed
from support.repository import EXPERIMENTS

T = 16
ARRIVED = 5  # robot 0's last move ends here
PATHS = np.array([[(min(x, ARRIVED), 1), (x, 4)] for x in range(T + 1)])
GRID = OccupancyGrid.from_occupied(np.zeros((20, 8), bool))
#: m/s and m: a held robot's largest speed and offset from its cell's centre in the windows' flight (equality rows,
#: met to about 1e-11 in a window's QP). The whole flight re-timed as one QP meets them to its own tolerance
#: (tests/continuous/test_retime.py); these tests are the windows' holds.
HELD = 1e-9


@pytest.fixture(autouse=True)
def _windows_flight(monkeypatch):
    """The windows' flight, not re-timed as a whole (these 16-step flights are short enough to be)."""
    unretimed(monkeypatch)


def _flight(monkeypatch, hold: bool, max_pieces: int = 0):
    # the fast durations made longer (FAST_SLOWER) fly the second window only without the hold, sooner than the
    # bold ones with it, and a hold never slows a window (test_a_hold_never_slows_a_window): these tests take
    # the ladder without them, where the hold is flown; so does the fast attempt with its first step as the
    # window before planned it (RecedingHorizon._follow), in the second window
    monkeypatch.setattr(rhm, "FAST_SLOWER", ())
    unfollowed(monkeypatch)
    if not hold:
        monkeypatch.setattr(rhm, "arrival_holds", lambda paths, settle: np.zeros((len(paths) - 1, paths.shape[1]), bool))
    return RecedingHorizon(PATHS, GRID, SmoothingConfig(max_pieces=max_pieces), 0.25, workers=1).run()


def _after_arrival(plan) -> tuple[np.ndarray, np.ndarray]:
    """Robot 0's speed and its distance from its cell's centre, sampled from its hold on."""
    t = np.linspace(plan.knot_times[ARRIVED + HOLD_SETTLE], plan.knot_times[-1], 400)
    tr = plan.trajectories[0]
    return np.linalg.norm(tr.evaluate(t, 1), axis=-1), np.linalg.norm(tr.evaluate(t, 0) - [ARRIVED, 1], axis=-1)


def test_which_steps_are_held():
    held = arrival_holds(PATHS, 2)
    assert held[:, 0].tolist() == [False] * (ARRIVED + 2) + [True] * (T - ARRIVED - 2)
    assert not held[:, 1].any()  # moves to the end
    still = np.repeat(PATHS[:1], 4, axis=0)  # nobody moves: held from the settle steps on
    assert arrival_holds(still, 1).tolist() == [[False, False]] + [[True, True]] * 2
    assert arrival_holds(PATHS[:1], 2).shape == (0, 2)


@pytest.mark.parametrize("max_pieces", [0, 31])
def test_an_arrived_robot_is_held_still_at_its_cell(monkeypatch, max_pieces):
    plan = _flight(monkeypatch, True, max_pieces)
    assert plan.certificate.ok and any(w.hold for w in plan.windows)
    v, off = _after_arrival(plan)
    assert v.max() < HELD and off.max() < HELD  # equality rows: at the centre
    assert count_stops(plan.trajectories).per_robot.tolist() == [0, 0]


def test_without_the_hold_it_drifts(monkeypatch):
    held = _flight(monkeypatch, True)
    plan = _flight(monkeypatch, False)
    assert plan.certificate.ok and not any(w.hold for w in plan.windows)
    v, off = _after_arrival(plan)
    assert v.max() > 0.1 and off.max() > 0.05
    assert count_stops(plan.trajectories).per_robot[0] >= 1
    assert plan.makespan_s == pytest.approx(held.makespan_s, rel=1e-9)


def test_a_hold_never_slows_a_window():
    """With the fast durations 5 and 10 % longer in the ladder, or the fast ones with the first step as the first
    window planned it, the second window flies them without the hold (with it they fail): its steps sooner than
    the bold durations that hold robot 0, which then drifts. (The whole toy flight is not sooner for it: 9.945 s
    against 9.937, the later windows starting from another state.)"""
    plan = RecedingHorizon(PATHS, GRID, SmoothingConfig(max_pieces=0), 0.25, workers=1).run()
    second = plan.windows[1]
    faster = {f"fast x{f:g}" for f in rhm.FAST_SLOWER} | {"fast" + rhm.FOLLOWED}
    assert second.attempt in faster and not second.hold
    assert any("with holds" in f for f in second.failed)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(rhm, "FAST_SLOWER", ())
        unfollowed(mp)
        held_plan = RecedingHorizon(PATHS, GRID, SmoothingConfig(max_pieces=0), 0.25, workers=1).run()
    bold = held_plan.windows[1]
    assert bold.hold and not bold.attempt.startswith("fast")
    flown = slice(0, second.c - second.a)  # the same first window before: the same start
    assert second.durations[flown].sum() < bold.durations[flown].sum()


def test_the_hold_is_pinned_only_where_the_window_can_fly_it():
    """Not in the window's first piece (its start state is given), not in a piece that also spans unheld
    steps, and a robot that does not start at rest at its cell gets HOLD_SETTLE steps more."""
    rh = RecedingHorizon(PATHS, GRID, SmoothingConfig(max_pieces=0), 0.25, workers=1)
    a, b, robots = ARRIVED + HOLD_SETTLE, ARRIVED + HOLD_SETTLE + 8, np.array([0, 1])
    at_rest = np.zeros((2, 4, 2))
    at_rest[:, 0] = rh.X[a]
    moving = at_rest.copy()
    moving[0, 1] = [0.3, 0.0]

    def pinned(start, merged=None) -> list[int]:
        reg = rh._held_regions(a, b, robots, start, merged)
        width = (reg.upper - reg.lower)[:, 0].max(axis=-1)  # robot 0's box, per step
        assert (reg.upper - reg.lower)[:, 1].min() > 0.4  # robot 1 moves on: never held
        return np.flatnonzero(width <= 2 * (rh.slack + HOLD_ROOM) + 1e-12).tolist()

    assert pinned(at_rest) == [1]  # held from the window's start, pinned after its first piece
    assert pinned(moving) == [HOLD_SETTLE]
    two_step_pieces = np.array([True, False] * 3 + [True])
    assert pinned(at_rest, two_step_pieces) == [2]
    assert pinned(moving, two_step_pieces) == [2]
    # a window from the arrival: held from its third step, which shares a piece with the unheld second
    a, b = ARRIVED, ARRIVED + 8
    at_rest[:, 0] = rh.X[a]
    assert pinned(at_rest) == [HOLD_SETTLE]
    assert pinned(at_rest, np.array([False, True, False, True, False, True, False])) == [3]
    a, b = 0, ARRIVED + HOLD_SETTLE + 1  # held in its last step only: the window ends at rest there anyway
    at_rest[:, 0] = rh.X[a]
    assert pinned(at_rest) == []
    assert rh._held_regions(0, 4, robots, at_rest, None).upper.tolist() == rh.regions.window(0, 4, robots).upper.tolist()


def test_a_hold_on_an_oriented_region_is_refused():
    """A wait's region is always a box; a held oriented one would be a bug upstream, and is not shrunk silently."""
    from mrfswarm.continuous.regions import Regions, hold_regions

    reg = Regions(np.broadcast_to(np.eye(2), (1, 1, 2, 2)).copy(), np.zeros((1, 1, 2)), np.ones((1, 1, 2)),
                  np.array([[True]]), 0.25)
    with pytest.raises(AssertionError, match="oriented"):
        hold_regions(reg, np.array([[True]]), np.full((1, 1, 2), 0.5), 0.01)
    box = Regions(reg.axes, reg.lower, reg.upper, np.array([[False]]), 0.25)
    shrunk = hold_regions(box, np.array([[True]]), np.full((1, 1, 2), 0.5), 0.01)
    np.testing.assert_allclose(shrunk.lower, 0.49)
    np.testing.assert_allclose(shrunk.upper, 0.51)


def test_where_the_creep_rows_fail_the_holds_are_tried_alone(monkeypatch):
    """Robot 1 waits one step on its straight run (creep rows keep it moving there); with a creep speed no
    robot can fly, every attempt with the creep rows fails, and the holds are then tried without them:
    robot 0 is still held at its cell."""
    waits = np.array([[(min(x, ARRIVED), 1), (min(x, 7) if x <= 8 else x - 1, 4)] for x in range(T + 1)])
    monkeypatch.setattr(rhm, "CREEP_SPEED", 50.0)  # over v_max: the creep rows are infeasible
    monkeypatch.setattr(rhm, "FAST_SLOWER", ())  # as in _flight
    unfollowed(monkeypatch)
    plan = RecedingHorizon(waits, GRID, SmoothingConfig(max_pieces=0), 0.25, workers=1).run()
    assert plan.certificate.ok
    tried = [w for w in plan.windows if any("with creep rows with holds" in f for f in w.failed)]
    assert tried and all(w.hold and not w.creep for w in tried)
    v, off = _after_arrival(plan)
    assert v.max() < HELD and off.max() < HELD


def test_where_some_holds_fail_the_other_robots_are_still_held(monkeypatch):
    """clutter40 of the flight-quality bench: in its late windows (two steps per piece) a robot held at its cell
    cannot make way for a neighbour that swings back past it, so the holds of the whole window failed and every
    arrived robot drifted (0.25 stops per robot). Releasing the robots the window's solution without holds
    brings against a corridor's plane, the others stay held: fewer stops, the same steps and durations."""
    sys.path.insert(0, str(EXPERIMENTS / "bench"))
    from flight_quality import case_config

    unled(monkeypatch)  # the windows it was written on
    data, base = case_config("clutter40")
    # the plan of the "downhill" rule and congestion 5 (the default before the twenty-fourth session), whose windows
    # this test was written on
    cfg = from_dict(apply_overrides(data, ["simulation.enabled=false", "smoothing.enabled=false",
                                           "mrf.contested=downhill", "goal_potential.congestion=5"]), base)
    discrete = plan(cfg, progress=False)
    paths = discrete.discrete.paths

    def flight():
        return RecedingHorizon(paths, discrete.scenario.grid, cfg.smoothing, cfg.scenario.robot_radius,
                               cfg.smoothing.backend, qp_options(cfg), workers=1).run()

    partly = flight()
    fired = [w for w in partly.windows if w.released]
    assert fired, "no window released a hold: the test no longer covers it"
    assert all(w.hold for w in fired) and partly.certificate.ok
    held = arrival_holds(paths, HOLD_SETTLE)
    for w in fired:  # a released robot is one that was to be held there, and not every one of them
        assert all(held[w.a:w.b, i].any() for i in w.released)
        assert len(w.released) < held[w.a:w.b].any(axis=0).sum()
    monkeypatch.setattr(RecedingHorizon, "_releases", lambda self, *args: [])
    whole = flight()
    assert not any(w.released for w in whole.windows)
    assert not all(w.hold for w in whole.windows if w.a in {f.a for f in fired})
    assert partly.makespan_s == pytest.approx(whole.makespan_s, rel=1e-9)
    assert count_stops(partly.trajectories).per_robot.sum() < count_stops(whole.trajectories).per_robot.sum()


def test_the_previous_windows_durations_hold_the_arrived_robots(monkeypatch):
    """Where every profile fails and a window flies the previous window's durations, the arrived robots are held
    there too: flown unheld, the refined open field's windows that did so let 10 of its 50 arrived robots drift (one
    stop each). No bench map flies the previous durations since the held pieces' rows fix their variables
    (``formulation.WindowFormulation``), so here the toy flight's profiles are made too fast to fly in the steps
    every window shares with the one before (a tenth of their durations), and nothing else."""
    original = RecedingHorizon._profile_attempts
    overlap = SmoothingConfig().horizon - round(SmoothingConfig().horizon * SmoothingConfig().execution)

    def too_fast(self, a, c, b):
        attempts = original(self, a, c, b)
        if a == 0:
            return attempts
        return [(name, np.concatenate([0.1 * d[:overlap], d[overlap:]])) for name, d in attempts]

    monkeypatch.setattr(RecedingHorizon, "_profile_attempts", too_fast)
    flight = _flight(monkeypatch, True)
    previous = [w for w in flight.windows if w.attempt == "previous"]
    assert previous and all(w.hold for w in previous), [(w.a, w.attempt, w.hold) for w in flight.windows]
    assert flight.certificate.ok
    v, off = _after_arrival(flight)
    assert v.max() < HELD and off.max() < HELD
    assert count_stops(flight.trajectories).per_robot.tolist() == [0, 0]


def test_a_held_piece_is_fixed_by_one_row_per_variable():
    """The pinned step's piece: its own variables (both knots' derivatives, its bubbles) each fixed by one
    equality row (the position at the cell's centre, the rest 0), and none of its control-point region rows
    (repeating the same equalities in another basis left piqp short of iterations in clutter's late windows);
    solved, robot 0 rests exactly at its cell through the whole pinned step."""
    from mrfswarm.continuous.formulation import WindowFormulation, piece_maps

    rh = RecedingHorizon(PATHS, GRID, SmoothingConfig(max_pieces=0), 0.25, workers=1)
    a, b, robots = ARRIVED + HOLD_SETTLE, ARRIVED + HOLD_SETTLE + 4, np.array([0, 1])
    start = np.zeros((2, rh.cfg.derivative, 2))
    start[:, 0] = rh.X[a]
    start[1, 1] = [1.0, 0.0]
    free_spec = rh._spec(a, b, robots, start, np.zeros(0, dtype=int))
    held_spec = rh._spec(a, b, robots, start, np.zeros(0, dtype=int), hold=True)
    durations = rh.nominal[a:b]
    qp_free, qp_held = WindowFormulation(free_spec).qp(durations), WindowFormulation(held_spec).qp(durations)
    pm = piece_maps(rh.cfg.degree, rh.cfg.derivative)
    form = WindowFormulation(held_spec)
    eq = np.flatnonzero(qp_held.l == qp_held.u)
    A = qp_held.A.tocsr()
    singles = [i for i in eq if A[i].nnz == 1]
    cols = sorted(int(A[i].indices[0]) for i in singles)
    # robot 0 (first in the window), step 1 (the pinned one), both coordinates: knot 1's and knot 2's derivatives
    # and piece 1's bubbles; knot 0 and the window's end are fixed by the ends' rows already
    expected = sorted(d * form.per_dim + pm.stride + k for d in range(2) for k in range(pm.stride + rh.cfg.derivative))
    assert set(expected) <= set(cols) and len(cols) - len(set(cols)) == 0
    values = {int(A[i].indices[0]): qp_held.l[i] for i in singles}
    centre = rh.X[a + 1, 0] - rh.X[a, 0]  # the variables are relative to the window's start
    assert [values[d * form.per_dim + pm.stride] for d in range(2)] == pytest.approx(centre.tolist(), abs=1e-12)
    assert [values[d * form.per_dim + 2 * pm.stride] for d in range(2)] == pytest.approx(centre.tolist(), abs=1e-12)
    # the held step's region rows are free (no entries, infinite bounds); robot 1's and the other steps' stay
    assert qp_held.A.shape[0] == qp_free.A.shape[0] + len(expected)
    assert np.isinf(qp_held.l).sum() - np.isinf(qp_free.l).sum() == (pm.rows[0]) * 2
    import solvers.qp

    sol = solvers.qp.solve(qp_held, backend="piqp")
    Y, _ = form.unpack(sol.x)
    assert np.abs(Y[0, 1:3, 1:]).max() < 1e-9 and np.abs(Y[0, 1:3, 0] - rh.X[a + 1, 0]).max() < 1e-9  # unpacked: absolute
