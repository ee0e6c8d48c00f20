"""Flight backends: the batched RotorPy simulation (torch, optional) against one simulation per robot."""

import numpy as np
import pytest

import mrfswarm
from mrfswarm.errors import ConfigError, SolverNotFound
from support.repository import EXPERIMENTS

pytest.importorskip("rotorpy")

from mrfswarm import simulation


def test_backend_names_and_missing_modules(monkeypatch):
    with pytest.raises(ConfigError, match="simulation.backend = 'gpu'"):
        simulation.resolve_backend("gpu")
    assert simulation.resolve_backend("processes") == "processes"
    monkeypatch.setattr(simulation, "BATCHED_MODULES", ("torch", "a_module_that_is_not_installed"))
    assert not simulation.batched_available()
    assert simulation.resolve_backend("auto") == "processes"
    with pytest.raises(SolverNotFound, match=r'a_module_that_is_not_installed: pip install "mrfswarm\[batched\]"'):
        simulation.resolve_backend("batched")


def test_config_rejects_an_unknown_backend():
    with pytest.raises(ConfigError, match="simulation.backend"):
        mrfswarm.load_config(None, ['simulation.backend="gpu"'])
    assert mrfswarm.load_config(None, ['simulation.backend="processes"']).simulation.backend == "processes"


@pytest.fixture(scope="module")
def trajectories():
    pytest.importorskip("torch")
    r = mrfswarm.plan(mrfswarm.load_config(EXPERIMENTS / "free5.toml", ["simulation.enabled=false"]), progress=False)
    return r.continuous.trajectories[:3], r.continuous.j_max, r.config.scenario.altitude


def test_batched_flight_equals_one_simulation_per_robot(trajectories):
    trs, _, alt = trajectories
    batched = simulation.fly_batched(trs, alt, 100.0, duration=3.0)
    for tr, fb in zip(trs, batched):
        fp = simulation.fly(tr, alt, 100.0, duration=3.0)
        assert np.array_equal(fb.times, fp.times) and np.array_equal(fb.desired, fp.desired)
        assert np.abs(fb.positions - fp.positions).max() < 1e-6  # RK4 vs adaptive RK45 at 100 Hz
        assert fb.tracking_error.max() > 1e-3  # a real flight, not the reference copied


def test_batched_swarm_flight_stays_within_the_tracking_bound(trajectories):
    """The linear-model bound (same gains as SE3Control) holds for the batched vehicles."""
    trs, jerk, alt = trajectories
    import torch

    threads = torch.get_num_threads()
    from mrfswarm.scenario import build_scenario

    grid = build_scenario(mrfswarm.load_config(EXPERIMENTS / "free5.toml")).grid
    speed = max(float(np.linalg.norm(tr.evaluate(np.linspace(0, tr.duration, 2001), 1), axis=1).max()) for tr in trs)
    f = simulation.fly_swarm(trs, alt, grid, 100.0, jerk=jerk, speed=speed, backend="batched")
    assert torch.get_num_threads() == threads and torch.get_default_dtype() == torch.float32
    assert f.tracking_bound == pytest.approx(simulation.tracking_bound(jerk, speed))
    assert 0.2 * f.tracking_bound < f.max_tracking_error <= f.tracking_bound  # max jerk and max speed need not coincide
    assert len(f.flights) == 3 and f.min_separation > 0.5
