"""The paper's scenarios through the public API (discrete stage)."""

import numpy as np
import pytest
from scipy.spatial import ConvexHull

import mrfswarm
from mrfswarm.discrete.safety import discrete_violations
from mrfswarm.pipeline import plan
from support.repository import EXPERIMENTS

DISCRETE = ["smoothing.enabled=false"]


@pytest.mark.parametrize("name", ["corridor", "blocks", "corridor10"])
def test_swarm_reaches_the_goal_region(name):
    r = plan(mrfswarm.load_config(EXPERIMENTS / f"{name}.toml", DISCRETE))
    assert r.discrete.converged and r.metrics.reached_goal
    assert r.metrics.final_goal_distance <= r.scenario.goal_radius
    assert r.metrics.min_separation >= 1.0 - 1e-9
    assert r.metrics.min_obstacle_clearance >= 0.5 - 1e-9
    assert discrete_violations(r.discrete.paths, r.scenario.grid.free) == []


def test_free_space_five_robots_settle_into_pentagons():
    """The paper's Fig. 6a claim, over 20 sampled starts: converged within a few steps, near-equal
    nearest-neighbour distances, and a pentagon in most runs (a centred square otherwise)."""
    cfg = mrfswarm.load_config(EXPERIMENTS / "free5.toml", DISCRETE)
    pentagons = 0
    for seed in range(20):
        r = plan(cfg, seed=seed)
        assert r.discrete.converged and r.discrete.n_steps <= 8
        f = r.discrete_paths_world()[-1]
        d = np.hypot(*(f[:, None] - f[None]).transpose(2, 0, 1))
        np.fill_diagonal(d, np.inf)
        nn = d.min(axis=1)
        assert nn.max() / nn.min() < 1.2
        pentagons += len(ConvexHull(f).vertices) == 5
    assert pentagons >= 15


def test_free_space_pentagon_from_config():
    r = plan(mrfswarm.load_config(EXPERIMENTS / "free5.toml", DISCRETE))
    assert r.discrete.converged and r.discrete.n_steps <= 10
    assert r.metrics.reached_goal is None
    final = r.discrete_paths_world()[-1]
    d = np.hypot(*(final[:, None] - final[None]).transpose(2, 0, 1))
    np.fill_diagonal(d, np.inf)
    nn = d.min(axis=1)
    assert nn.max() / nn.min() < 1.1
    assert len(ConvexHull(final).vertices) == 5


def test_a_circulating_swarm_stops_as_stalled():
    r = plan(mrfswarm.load_config(EXPERIMENTS / "blocks12.toml", DISCRETE + ["mrf.patience=15"]))
    assert r.discrete.stop_reason == "stalled" and not r.discrete.converged
    e = r.discrete.energy
    assert np.argmin(e) == len(e) - 1  # the plan ends at the swarm energy's minimum
    assert len(r.discrete.steps) == len(e) - 1 == r.discrete.n_steps
    assert all(len(v) == r.discrete.n_steps for v in r.discrete.timings.values())
    longer = plan(mrfswarm.load_config(EXPERIMENTS / "blocks12.toml", DISCRETE + ["mrf.patience=15", "mrf.max_steps=300"]))
    assert longer.discrete.n_steps == r.discrete.n_steps  # deterministic
    assert r.metrics.reached_goal


def test_paths_are_in_metres_in_the_map_frame():
    r = plan(mrfswarm.load_config(EXPERIMENTS / "corridor.toml", DISCRETE + ["mrf.max_steps=3"]))
    w = r.discrete_paths_world()
    assert w[0].tolist() == [[4, 16], [4, 18], [4, 20], [4, 22], [4, 24]]


@pytest.mark.parametrize("n, sets, said", [(1000, [], True), (100, [], False), (1000, ["mrf.arrival=false"], False)])
def test_a_swarm_starting_in_its_goal_region_is_said(caplog, n, sets, said):
    """1000 robots on swarm100's field: the goal region (4 free cells per robot) held 192 of them at the start, and
    the plan ended "arrived" 43 m from the goal without a word (a scale tour)."""
    from mrfswarm.config import load_config
    from mrfswarm.scenario import build_scenario

    with caplog.at_level("WARNING", logger="mrfswarm.scenario"):
        build_scenario(load_config(EXPERIMENTS / "swarm100.toml", [f"scenario.start.n_robots={n}", *sets]))
    assert ("of 1000 robots start inside the goal region" in caplog.text) == said
