"""The default time grid: speed profiles from the robots' motion and the limits."""

from __future__ import annotations

import numpy as np
import pytest

from mrfswarm.continuous.time_grid import motion_durations, motion_profile, rest_times, segment_times


def test_motion_durations_cruise_straight_and_slow_for_reversals():
    straight = np.array([[[i, 0]] for i in range(12)])  # (T + 1, 1, 2): 11 one-cell moves along x
    d = motion_durations(straight, 1.0, 2.0, 1.0)
    assert np.allclose(d[4:7], 0.5)  # cruising at v_max in the middle
    assert d[0] > 0.5 and d[-1] > 0.5  # speeding up from rest, slowing down to rest
    back = np.array([[[i, 0]] for i in range(6)] + [[[i, 0]] for i in range(4, -1, -1)])
    db = motion_durations(back, 1.0, 2.0, 1.0)
    assert db[4] > d[4] and db[5] > d[5]  # the reversal at step 5 slows the steps around it
    # the swarm's durations change no faster than a speed profile can: no short step between long ones
    assert np.all(np.abs(np.diff(1.0 / db)) <= 1.0 * np.maximum(db[:-1], db[1:]) + 1e-9)


def test_segment_times_are_the_trapezoid():
    # from rest to rest over 4 m at a = 1, v_max = 10: a triangle, 2 * sqrt(4 / 1)
    assert segment_times(np.array([4.0]), np.array([0.0]), np.array([0.0]), 10.0, 1.0)[0] == 4.0
    # cruise at v_max: 1 m at 2 m/s
    assert segment_times(np.array([1.0]), np.array([2.0]), np.array([2.0]), 2.0, 1.0)[0] == 0.5
    assert segment_times(np.array([0.0]), np.array([0.0]), np.array([0.0]), 2.0, 1.0)[0] == 0.0


def test_a_window_brakes_to_rest_at_its_end_and_keeps_the_flight_pace_before():
    straight = np.array([[[i, 0]] for i in range(30)])  # 29 one-cell moves along x
    prof = motion_profile(straight, 1.0, 2.0, 1.0)
    whole = prof.durations
    win = prof.window(10, 18)  # a window of 8 steps in the cruise, at rest at step 18
    np.testing.assert_allclose(win[:4], whole[10:14])  # the executed half flies at the flight's pace
    assert win[-1] > 2 * whole[17]  # the last step brakes to rest
    # braking from v to 0 at a over the tail: the tail lasts at least v / a
    assert win[4:].sum() >= 2.0 / 1.0 - 1e-9
    np.testing.assert_allclose(prof.window(0, 29), whole)  # the whole flight: the same profile


def test_a_single_step_wait_drifts_instead_of_stopping_unless_the_robot_turns_back():
    """Robot 0 runs along x and waits one step; robot 1 runs on throughout. With a drift the waiting robot
    keeps some speed through the wait (its knots are not at rest), so the steps around it are shorter; a wait
    before a turn of more than 90 degrees, and a wait of two steps, still stop."""
    run = [0, 1, 2, 3, 4, 4, 5, 6, 7, 8]
    def pair(xs, ys=(0,) * 10):
        return np.array([[[x, y], [i, 5]] for i, (x, y) in enumerate(zip(xs, ys))], dtype=float)
    stop, drift = (motion_profile(pair(run), 1.0, 2.0, 1.0, d) for d in (0.0, 0.5))
    assert drift.durations.sum() < stop.durations.sum() - 0.2
    assert np.allclose(drift.durations[:2], stop.durations[:2]) and drift.durations[3] < stop.durations[3]
    back = [0, 1, 2, 3, 4, 4, 3, 2, 1, 0], [0, 0, 0, 0, 0, 0, 1, 2, 3, 4]  # turns 135 degrees after the wait
    assert np.allclose(motion_profile(pair(*back), 1.0, 2.0, 1.0, 0.5).durations,
                       motion_profile(pair(*back), 1.0, 2.0, 1.0, 0.0).durations)
    long = [0, 1, 2, 3, 4, 4, 4, 5, 6, 7]  # two steps of waiting: no room to drift through
    assert np.allclose(motion_profile(pair(long), 1.0, 2.0, 1.0, 0.5).durations,
                       motion_profile(pair(long), 1.0, 2.0, 1.0, 0.0).durations)


def test_rest_times_are_the_fastest_jerk_limited_start():
    v, a, j = 2.0, 4.0, 4.0  # a triangle of acceleration: j t up to sqrt(v j) = 2.83 < a_max, then down
    s = np.array([0.0, 0.01, 0.1, 0.2])  # within the first ramp (0.71 s, 0.24 m): s = j t^3 / 6
    np.testing.assert_allclose(rest_times(s, v, a, j), np.cbrt(6 * s / j), atol=1e-5)
    end = rest_times(np.array([v * np.sqrt(v / j)]), v, a, j)[0]  # reaches v_max after 2 sqrt(v / j) = 1.414 s,
    assert end == pytest.approx(2 * np.sqrt(v / j), abs=1e-4)  # having covered v sqrt(v / j)
    far = rest_times(np.array([10.0, 12.0]), v, a, j)
    assert far[1] - far[0] == pytest.approx(2.0 / v)  # then cruise
    # with a_max reached (j = 40): a ramp of 0.1 s, then a_max; the constant-acceleration trapezoid is a bound below
    d = np.linspace(0.01, 3.0, 50)
    fast = rest_times(d, v, a, 40.0)
    trapezoid = segment_times(d, np.zeros_like(d), np.full_like(d, v), v, a)  # ends at v_max: at most
    assert np.all(np.diff(fast) > 0) and np.all(fast >= np.minimum(trapezoid, np.sqrt(2 * d / a)) - 1e-9)
    assert np.all(rest_times(d, v, a, 4.0) > fast)  # the lower the jerk, the slower


def test_a_window_stop_keeps_to_the_jerk_limit_and_the_flights_end_does_not():
    """With the limits, the steps before a window's stop at b < T last what a jerk-limited stop over the swarm's
    progress takes at least; the flight's own end (b = T, flown) keeps the trapezoids."""
    straight = np.array([[[i, 0]] for i in range(30)])
    v, a, j = 2.0, 4.0, 4.0
    plain = motion_profile(straight, 1.0, v, 5.6)  # the fast profile's acceleration: 4 x sqrt(v j) / 2
    limited = motion_profile(straight, 1.0, v, 5.6, limits=(v, a, j))
    win = limited.window(10, 18)
    stop = -np.diff(rest_times(np.arange(8, -1, -1.0), v, a, j))  # 1 m steps, 8 .. 0 m before the stop
    assert np.all(win >= stop - 1e-12) and np.any(win > plain.window(10, 18) + 0.1)  # the stop is longer
    assert win[-3:].sum() >= rest_times(np.array([3.0]), v, a, j)[0] - 1e-12
    np.testing.assert_allclose(win[:4], plain.window(10, 18)[:4])  # far from the stop: the same pace
    np.testing.assert_allclose(limited.window(20, 29), plain.window(20, 29))  # the flight's end: no floor
    np.testing.assert_allclose(limited.durations, plain.durations)


def test_reachable_speed_is_the_top_of_the_fastest_rest_to_rest_move():
    from mrfswarm.continuous.time_grid import reachable_speed

    assert reachable_speed(30.0, 2.0, 4.0, 4.0) == 2.0  # a long way reaches v_max
    # jerk alone (a_max out of reach): an S-curve to v over half the way, v^1.5 / sqrt(j) = L / 2
    L, j = 2.0, 4.0
    assert reachable_speed(L, 50.0, 100.0, j) == pytest.approx((L / 2 * np.sqrt(j)) ** (2 / 3), rel=1e-3)
    # with a_max binding: the fastest start to v (rest_times's curve at v_max = v) ends at zero acceleration half
    # the way along, and takes its own time there (no cruise)
    from mrfswarm.continuous.time_grid import _rest_curve

    for L in (12.0, 3.0, 0.5):
        v = reachable_speed(L, 50.0, 4.0, 4.0)
        t, s = _rest_curve(v, 4.0, 4.0)
        assert s[-1] == pytest.approx(L / 2, rel=1e-4), (L, v)
    assert reachable_speed(12.0, 50.0, 4.0, 4.0) > 4.0  # a_max reached on 12 m: the trapezoid branch


def test_a_looser_speed_limit_does_not_slow_a_short_flight():
    """Four robots around a wall on a 14 x 10 m map: their ways (about 12 m) reach 5.5 m/s at most under a_max 4
    and j_max 4. Raising v_max past that changes nothing the robots can do; the profiles' acceleration was set
    for a speed change of v_max (8 m/s^2 at v_max 20 instead of 4.6 for the speed they reach), every
    profile failed and the flight took 9.0 s against 6.1 at v_max 5."""
    from mrfswarm.config import apply_overrides, from_dict
    from mrfswarm.pipeline import plan

    data = {"scenario": {"map": {"kind": "boxes", "size": [14, 10], "boxes": [{"center": [7, 2.5], "size": [1, 5]}]},
                         "start": {"positions": [[1, 2], [1, 4], [2, 6], [3, 3]]}, "goal": [12, 3],
                         "goal_radius": 1.0}}
    makespan = {v: plan(from_dict(apply_overrides(data, ["simulation.enabled=false", f"smoothing.v_max={v}"])),
                        progress=False).continuous.makespan_s for v in (5, 20)}
    assert makespan[20] <= 1.1 * makespan[5], makespan


# a window of one step is made long enough to brake in (receding_horizon.braking_horizon: 4 steps at 2 m/s on 1 m
# cells), so it flies half of it and does not stop: no warning; flown to its end with the profiles off, it is said
@pytest.mark.parametrize("sets, warns", [((), False), (("smoothing.execution=1.0",), True),
                                         (("smoothing.horizon=1",), False),
                                         (("smoothing.horizon=1", "smoothing.speed=1.25"), True),
                                         (("smoothing.execution=1.0", "smoothing.seam=rest"), False)])
def test_windows_flown_to_their_end_are_said_to_stop_at_every_seam(sets, warns, caplog):
    """A continuous seam needs the next window to take over before the last one's end, where it plans the
    robots at rest: flying the whole window (execution 1, or a window of one step) stops there, and one warning
    says so (the paper's rest seams stop by design: no warning)."""
    from mrfswarm.config import SmoothingConfig, apply_overrides
    from mrfswarm.continuous import RecedingHorizon
    from mrfswarm.maps import OccupancyGrid

    smoothing = apply_overrides({}, list(sets)).get("smoothing", {})
    cfg = SmoothingConfig(**smoothing)
    paths = np.array([[[1 + k, 2], [1 + k, 4]] for k in range(12)])
    grid = OccupancyGrid.from_occupied(np.zeros((16, 8), bool))
    with caplog.at_level("WARNING"):
        RecedingHorizon(paths, grid, cfg, 0.25)
    assert ("flies every window to its end" in caplog.text) == warns, caplog.text
