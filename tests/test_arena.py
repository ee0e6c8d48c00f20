"""Arena scale (issue 19): 8 small robots in a 6 x 4 m arena drawn in 0.25 m cells.

``experiments/arena.toml`` and a second arena of another shape (a MovingAI map given a
resolution and an origin, 6 x 3.5 m, start sampled with the default spread), each planned
with the defaults but the robots' size and limits: every robot at the goal, the flight
certified and clean under the independent 500 Hz check with the 0.1 m radius.
"""

import numpy as np
import pytest

from mrfswarm.config import load_config
from mrfswarm.pipeline import plan
from support.repository import EXPERIMENTS

ARENA = EXPERIMENTS / "arena.toml"
SMOOTH = ["simulation.enabled=false", "smoothing.check_rate_hz=500"]

# 6 x 3.5 m at 0.25 m cells: a block in the middle and a wall stub from the top edge
OTHER_ROWS = [
    "........................",
    "........................",
    "........................",
    "........................",
    "...........@@...........",
    "...........@@...........",
    "...........@@...........",
    "...........@@...........",
    "........................",
    "........................",
    "................@.......",
    "................@.......",
    "................@.......",
    "................@.......",
]


def other_arena(tmp_path):
    (tmp_path / "arena.map").write_text("type octile\nheight 14\nwidth 24\nmap\n" + "\n".join(OTHER_ROWS) + "\n")
    (tmp_path / "arena.toml").write_text(
        '[scenario]\nmap = { kind = "movingai", path = "arena.map", resolution = 0.25, origin = [0.125, 0.125] }\n'
        "start = { center = [0.6, 1.75], n_robots = 8, seed = 4 }\ngoal = [5.5, 3.0]\nrobot_radius = 0.1\n"
        "[smoothing]\nv_max = 1.0\na_max = 2.0\n")
    return tmp_path / "arena.toml"


def check_arena(r, n_robots=8, radius=0.1):
    s = r.summary()
    assert s["n_robots"] == n_robots and s["robots_at_goal"] == n_robots and s["reached_goal"] is True
    assert all(robot["at_goal"] for robot in s["robots"])
    # the discrete invariant at 0.25 m cells: one cell apart, half a cell off walls
    assert s["min_separation_discrete"] >= 0.25 - 1e-12
    assert s["min_obstacle_clearance_discrete"] >= 0.125 - 1e-12
    # a goal region of cells, not of the paper's metres: 3 cells + the radius holding 32 free cells
    assert s["goal_region_radius_m"] < 2.0
    return s


def test_arena_discrete_stage_reaches_the_goal():
    r = plan(load_config(ARENA, ["smoothing.enabled=false", "simulation.enabled=false"]))
    s = check_arena(r)
    assert r.scenario.grid.shape == (24, 16) and r.scenario.grid.extent == (0.0, 6.0, 0.0, 4.0)
    assert r.scenario.morse.d_min == pytest.approx(8.42 * 0.25, abs=0.01)  # 2.1 m: the swarm fits the arena
    assert s["mrf_steps"] <= 60  # a crossing of ~20 cells; the paper's lengths in metres took 45 steps and spread the swarm


def test_arena_flies_safely_to_the_goal():
    r = plan(load_config(ARENA, SMOOTH))
    s = check_arena(r)
    assert s["certificate"]["ok"] is True and s["failure"] is None
    sampled = s["sampled_check"]
    assert sampled["rate_hz"] == 500.0 and not sampled["in_obstacle"]
    assert sampled["min_separation_m"] >= 2 * 0.1 - 1e-9 and sampled["min_clearance_m"] >= 0.1 - 1e-9
    assert s["achieved"]["v_max"] <= 1.0 + 1e-9 and s["achieved"]["a_max"] <= 2.0 + 1e-9
    # one piece per MRF step, every robot; ends at its last cell (metres)
    ends = np.array([tr(tr.duration)[:2] for tr in r.continuous.trajectories])
    np.testing.assert_allclose(ends, r.discrete_paths_world()[-1], atol=1e-6)


def test_another_arena_flies_safely_to_the_goal(tmp_path):
    r = plan(load_config(other_arena(tmp_path), SMOOTH))
    assert r.scenario.grid.resolution == 0.25 and r.scenario.grid.extent == (0.0, 6.0, 0.0, 3.5)
    s = check_arena(r)
    assert s["certificate"]["ok"] is True and s["failure"] is None
    sampled = s["sampled_check"]
    assert sampled["min_separation_m"] >= 2 * 0.1 - 1e-9 and sampled["min_clearance_m"] >= 0.1 - 1e-9
