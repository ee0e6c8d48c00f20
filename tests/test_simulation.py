"""Quadrotors (RotorPy) flying the planned trajectories: tracking bound and separation."""

import numpy as np
import pytest

import mrfswarm
from mrfswarm.pipeline import plan
from support.repository import EXPERIMENTS

pytest.importorskip("rotorpy")

from rotorpy.controllers.quadrotor_control import SE3Control  # noqa: E402
from rotorpy.vehicles.crazyflie_params import quad_params  # noqa: E402
from scipy import signal  # noqa: E402

from mrfswarm.simulation import drag, fly, tracking_bound, tracking_gain  # noqa: E402

#: Crazyflie 2.x: 92 mm between opposite motors, so two vehicles touch below about 0.1 m apart.
CRAZYFLIE_DIAMETER = 0.1


def linear_model():
    """(H_j, H_d, static jerk gain): jerk and disturbance-acceleration to error, written out independently."""
    ctrl = SE3Control(quad_params)
    kp, kd, kR, kw = ctrl.kp_pos[0], ctrl.kd_pos[0], ctrl.kp_att, ctrl.kd_att
    D = np.array([quad_params["tau_m"], 1.0, kw, kR])
    num = np.polysub(D, [kR])[:-1]
    den = np.polyadd(np.polymul([1.0, 0.0, 0.0], D), kR * np.array([kd, kp]))
    return signal.lti(num, den), signal.lti(D, den), float(kw / (kR * kp))  # static gain num(0) / den(0)


def test_tracking_gain_of_the_linear_model():
    sys, _, static = linear_model()
    g = tracking_gain("crazyflie")
    assert g >= static - 1e-9  # an L1 norm is at least the static gain
    assert 0.02 < g < 0.05
    # the bound is tight for a long constant jerk: the response settles at the static gain
    t = np.linspace(0, 20, 20001)
    _, e, _ = signal.lsim(sys, np.ones_like(t), t)
    assert abs(e[-1]) == pytest.approx(static, rel=1e-3) and np.abs(e).max() <= g


def test_the_linear_model_explains_rotorpys_tracking_error():
    """The justification of the bound: the linearized loop, driven by the reference's jerk and by
    rotor drag at the reference's speed, predicts the flown error."""
    # at the 1.25 m/s cruise of the earlier default: the share of drag in the error (last line) is a fact of this
    # flight; on the default grid (from the limits) free5 flies jerkier and jerk's term is 0.79 of the error
    r = plan(mrfswarm.load_config(EXPERIMENTS / "free5.toml", ["simulation.enabled=false", "smoothing.speed=1.25"]))
    sys_j, sys_d, _ = linear_model()
    c1, c2 = drag("crazyflie")
    assert c1 == pytest.approx(0.244, abs=0.01) and c2 == 0.0
    # the robot and axis that move the most
    spans = [np.ptp(tr.evaluate(np.linspace(0, tr.duration, 200)), axis=0) for tr in r.continuous.trajectories]
    i, ax = np.unravel_index(np.argmax(spans), (len(spans), 2))
    tr = r.continuous.trajectories[i]
    f = fly(tr, r.config.scenario.altitude, 100.0)
    _, e_j, _ = signal.lsim(sys_j, tr.evaluate(f.times, derivative=3)[:, ax], f.times)
    _, e_d, _ = signal.lsim(sys_d, -c1 * tr.evaluate(f.times, derivative=1)[:, ax], f.times)
    e_lin = e_j - e_d
    e_sim = f.desired[:, ax] - f.positions[:, ax]
    assert np.corrcoef(e_sim, e_lin)[0, 1] > 0.9
    assert np.abs(e_sim).max() == pytest.approx(np.abs(e_lin).max(), rel=0.25)
    # without the drag term the model misses most of it: drag is what the bound must include
    assert np.abs(e_j).max() < 0.6 * np.abs(e_sim).max()


@pytest.mark.slow
def test_flown_corridor_keeps_the_separation_within_the_bound():
    # the default corridor: its flight's own maxima of jerk and speed bound the tracking error to 17.9 cm, so that
    # twice it leaves more than a Crazyflie's diameter (10 cm) of the 0.5 m safety distance (the limits' own bound,
    # 22.7 cm, would leave 4.5 cm). The fast profile at 3 x with the octagon limits used more jerk (a bound of
    # 20.2 cm, 9.7 cm guaranteed) and this test planned with j_max = 3 for a while. Since the leading attempt (issue
    # 18) its flight's jerk bounds it to 19.6 cm: 10.8 cm guaranteed.
    r = plan(mrfswarm.load_config(EXPERIMENTS / "corridor.toml"))
    f, c = r.flight, r.continuous
    assert f.tracking_bound == pytest.approx(tracking_bound(c.j_max, c.v_max))
    assert f.max_tracking_error <= f.tracking_bound
    # each flown robot is within the bound of its trajectory, so the pair within twice that
    assert f.min_separation >= c.min_separation - 2 * f.tracking_bound
    radius = r.config.scenario.robot_radius
    assert f.min_separation >= 2 * radius - 2 * f.tracking_bound > CRAZYFLIE_DIAMETER
    assert not f.in_obstacle and f.min_clearance >= radius - f.tracking_bound
    s = r.summary()["simulation"]
    assert s["max_tracking_error_m"] <= s["tracking_error_bound_m"]
    assert s["guaranteed_clearance_m"] == pytest.approx(radius - f.tracking_bound) and s["guaranteed_clearance_m"] > 0
    assert set(s["max_tracking_error_axis_m"]) == set(s["rms_tracking_error_axis_m"]) == {"x", "y", "z"}
    assert max(s["max_tracking_error_axis_m"].values()) <= s["max_tracking_error_m"]


# --- 3-D: the trajectories' own z ----------------------------------------------------------------


def test_flat_outputs_take_a_3d_trajectorys_z_and_a_2d_ones_altitude():
    from mrfswarm.simulation import flat_outputs
    from support.flight3d import window_flight

    tr3 = window_flight(2, step_s=1.0).trajectories[1]
    t = np.linspace(0.0, tr3.duration, 77)
    x3 = flat_outputs(tr3, t, altitude=9.0)
    assert x3.shape == (5, 77, 3)
    for k in range(5):
        assert np.array_equal(x3[k], tr3.evaluate(t, derivative=k))
    assert np.ptp(x3[0, :, 2]) > 1.0  # a real z, not the altitude
    tr2 = mrfswarm.trajectory.PiecewisePolynomial(tr3.durations, tr3.coefficients[..., :2])
    x2 = flat_outputs(tr2, t, altitude=1.25)
    assert np.array_equal(x2[:, :, :2], x3[:, :, :2])
    assert np.all(x2[0, :, 2] == 1.25) and np.all(x2[1:, :, 2] == 0.0)


def test_a_3d_trajectory_is_flown_in_3d_with_the_error_per_axis():
    from mrfswarm.trajectory import max_derivative_norm
    from support.flight3d import window_flight

    tr = window_flight(5, step_s=1.0).trajectories[4]  # climbs 1.5 m to the window in its first 10 s
    f = fly(tr, altitude=5.0, rate_hz=100.0, duration=12.0)
    assert np.allclose(f.desired, tr.evaluate(f.times))  # the commanded z is the trajectory's (not 5 m)
    assert np.ptp(f.positions[:, 2]) > 1.0 and np.abs(f.positions[:, 2] - 5.0).min() > 2.0
    e = f.axis_error
    assert e.shape == (len(f.times), 3) and np.allclose(np.linalg.norm(e, axis=1), f.tracking_error)
    assert e[:, 2].max() > 1e-3  # z is flown, not copied
    bound = tracking_bound(max_derivative_norm(tr, 3)[0], max_derivative_norm(tr, 1)[0])
    assert f.tracking_error.max() <= bound
    assert e[:, 2].max() < e[:, :2].max()  # thrust tracks z faster than the tilt tracks x and y (module docstring)


def test_swarm_measures_report_the_error_per_axis():
    from mrfswarm.maps import OccupancyGrid
    from mrfswarm.simulation import Flight, _measure

    t = np.arange(4) * 0.1
    desired = np.zeros((4, 3))
    flown = [desired + [[0.0, 0.0, 0.0], [0.1, 0.0, -0.02], [0.0, 0.05, 0.0], [0.0, 0.0, 0.0]],
             desired + [3.0, 0.0, 0.0] + [[0.0, 0.0, 0.03], [0.0, 0.0, 0.0], [0.0, -0.2, 0.0], [0.0, 0.0, 0.0]]]
    flights = [Flight(t, p, desired + [3.0 * i, 0.0, 0.0]) for i, p in enumerate(flown)]
    s = _measure(flights, OccupancyGrid.from_occupied(np.zeros((8, 8), dtype=bool)), "crazyflie", None, None)
    assert s.max_axis_error == pytest.approx((0.1, 0.2, 0.03))
    err = np.concatenate([np.abs(p - f.desired) for p, f in zip(flown, flights)])
    assert s.rms_axis_error == pytest.approx(tuple(np.sqrt((err**2).mean(axis=0))))
    assert s.per_axis() == {"max_tracking_error_axis_m": {"x": pytest.approx(0.1), "y": pytest.approx(0.2),
                                                          "z": pytest.approx(0.03)},
                            "rms_tracking_error_axis_m": dict(zip("xyz", s.rms_axis_error))}
    assert s.max_tracking_error == pytest.approx(0.2)


def test_a_flight_over_a_voxel_map_measures_clearance_in_3d():
    from mrfswarm.maps import OccupancyGrid
    from mrfswarm.simulation import Flight, _measure

    occ = np.zeros((6, 6, 6), dtype=bool)
    occ[3, 3, 0] = True  # a block on the floor, 1 m below the flight
    grid = OccupancyGrid.from_occupied(occ)
    t = np.arange(2) * 0.1
    p = np.array([[3.0, 3.0, 2.0], [3.0, 3.0, 2.0]])
    s = _measure([Flight(t, p, p)], grid, "crazyflie", None, None)
    assert s.min_clearance == pytest.approx(1.5) and not s.in_obstacle  # above it: the 3-D distance, not 0


def test_flown_separation_is_measured_in_the_downwash_metric_on_voxel_maps():
    """Two robots 0.8 m apart in z: 0.4 m apart with downwash 2 on a voxel map (below the 0.5 m safety
    distance), 0.8 m on a 2-D map whatever the downwash (it applies to voxel maps only)."""
    from mrfswarm.maps import OccupancyGrid
    from mrfswarm.simulation import Flight, _measure

    t = np.linspace(0.0, 1.0, 11)
    a = np.column_stack([t, np.full_like(t, 2.0), np.full_like(t, 2.0)])
    b = a + [0.0, 0.0, 0.8]
    flights = [Flight(t, p, p) for p in (a, b)]
    voxels = OccupancyGrid(np.zeros((5, 5, 5)))
    plane = OccupancyGrid(np.zeros((5, 5)))
    assert _measure(flights, voxels, "crazyflie", None, None, downwash=2.0).min_separation == pytest.approx(0.4)
    assert _measure(flights, voxels, "crazyflie", None, None).min_separation == pytest.approx(0.8)
    assert _measure(flights, plane, "crazyflie", None, None, downwash=2.0).min_separation == pytest.approx(0.8)


@pytest.mark.parametrize("backend", ["batched", "processes"])
def test_both_backends_measure_in_the_downwash_metric_and_say_which_flew(monkeypatch, backend):
    """fly_swarm's two branches hand the flights to the same measurement: the batched one lost the downwash (its
    stacked robots measured 0.8 m apart instead of 0.4), and result.json could not say which backend flew."""
    from mrfswarm import simulation
    from mrfswarm.maps import OccupancyGrid
    from mrfswarm.simulation import Flight, fly_swarm
    from mrfswarm.trajectory.polynomial import PiecewisePolynomial

    t = np.linspace(0.0, 1.0, 11)
    a = np.column_stack([t, np.full_like(t, 2.0), np.full_like(t, 2.0)])
    stacked = [Flight(t, p, p) for p in (a, a + [0.0, 0.0, 0.8])]
    monkeypatch.setattr(simulation, "check_available", lambda vehicle, backend="auto": None)
    monkeypatch.setattr(simulation, "batched_available", lambda: True)  # its flights are the fake's below
    monkeypatch.setattr(simulation, "fly_batched", lambda trs, *args, **kw: stacked)
    monkeypatch.setattr(simulation, "_fly_job", lambda job: stacked[int(job[0].coefficients[0, 0, 0])])
    trs = [PiecewisePolynomial(np.array([1.0]), np.array([[[float(i)], [0.0]]])) for i in range(2)]  # robot i
    f = fly_swarm(trs, 1.0, OccupancyGrid(np.zeros((5, 5, 5))), backend=backend, workers=1, progress=False,
                  downwash=2.0)
    assert f.backend == backend
    assert f.min_separation == pytest.approx(0.4)


@pytest.mark.parametrize("robots, seconds, backend, said", [(100, 41.0, "processes", True),
                                                             (20, 30.0, "processes", False)])
def test_a_long_per_process_simulation_is_said(caplog, robots, seconds, backend, said):
    """swarm100.toml as shipped simulated for minutes with nothing said (a scale tour)."""
    from mrfswarm import pipeline

    with caplog.at_level("WARNING", logger="mrfswarm.pipeline"):
        pipeline._say_long_simulation(robots, seconds, 100.0, backend)
    assert ("simulating 100 robots for 41 s of flight each" in caplog.text) == said
