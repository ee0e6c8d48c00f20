"""Quadrotors (RotorPy) flying the planned trajectories: tracking bound and separation."""

from pathlib import Path

import numpy as np
import pytest

import mrfswarm
from mrfswarm.pipeline import plan

pytest.importorskip("rotorpy")

from rotorpy.controllers.quadrotor_control import SE3Control  # noqa: E402
from rotorpy.vehicles.crazyflie_params import quad_params  # noqa: E402
from scipy import signal  # noqa: E402

from mrfswarm.simulation import fly, tracking_gain  # noqa: E402

EXP = Path(__file__).resolve().parents[1] / "experiments"
#: Crazyflie 2.x: 92 mm between opposite motors, so two vehicles touch below about 0.1 m apart.
CRAZYFLIE_DIAMETER = 0.1


def linear_model():
    ctrl = SE3Control(quad_params)
    kp, kd, kR, kw = ctrl.kp_pos[0], ctrl.kd_pos[0], ctrl.kp_att, ctrl.kd_att
    D = np.array([quad_params["tau_m"], 1.0, kw, kR])
    num = np.polysub(D, [kR])[:-1]
    den = np.polyadd(np.polymul([1.0, 0.0, 0.0], D), kR * np.array([kd, kp]))
    return signal.lti(num, den), float(kw / (kR * kp))  # static gain num(0) / den(0) = k_w / (k_R k_p)


def test_tracking_gain_of_the_linear_model():
    sys, static = linear_model()
    g = tracking_gain("crazyflie")
    assert g >= static - 1e-9  # an L1 norm is at least the static gain
    assert 0.02 < g < 0.05
    # the bound is tight for a long constant jerk: the response settles at the static gain
    t = np.linspace(0, 20, 20001)
    _, e, _ = signal.lsim(sys, np.ones_like(t), t)
    assert abs(e[-1]) == pytest.approx(static, rel=1e-3) and np.abs(e).max() <= g


def test_the_linear_model_explains_rotorpys_tracking_error():
    """The justification of the bound: the linearized loop predicts the flown error."""
    r = plan(mrfswarm.load_config(EXP / "free5.toml", ["simulation.enabled=false"]))
    sys, _ = linear_model()
    # the robot and axis that move the most
    spans = [np.ptp(tr.evaluate(np.linspace(0, tr.duration, 200)), axis=0) for tr in r.continuous.trajectories]
    i, ax = np.unravel_index(np.argmax(spans), (len(spans), 2))
    tr = r.continuous.trajectories[i]
    f = fly(tr, r.config.scenario.altitude, 100.0)
    _, e_lin, _ = signal.lsim(sys, tr.evaluate(f.times, derivative=3)[:, ax], f.times)
    e_sim = f.desired[:, ax] - f.positions[:, ax]
    assert np.corrcoef(e_sim, e_lin)[0, 1] > 0.9
    assert np.abs(e_sim).max() == pytest.approx(np.abs(e_lin).max(), rel=0.25)


def test_flown_corridor_keeps_the_separation_within_the_bound():
    r = plan(mrfswarm.load_config(EXP / "corridor.toml"))
    f, c = r.flight, r.continuous
    assert f.tracking_bound == pytest.approx(tracking_gain() * c.j_max)
    assert f.max_tracking_error <= f.tracking_bound
    # each flown robot is within the bound of its trajectory, so the pair within twice that
    assert f.min_separation >= c.check.min_separation - 2 * f.tracking_bound
    safety = r.config.smoothing.safety_distance * r.scenario.grid.resolution
    assert f.min_separation >= safety - 2 * f.tracking_bound > CRAZYFLIE_DIAMETER
    assert not f.in_obstacle and f.min_clearance >= c.check.min_clearance - f.tracking_bound
    s = r.summary()["simulation"]
    assert s["max_tracking_error_m"] <= s["tracking_error_bound_m"]
    assert len(f.flights) == 5 and all(len(fl.times) == len(f.flights[0].times) for fl in f.flights)
