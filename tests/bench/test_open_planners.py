"""The open-planner comparison's translation to and from libMultiRobotPlanning's YAML (experiments/bench/open_planners.py)."""

import sys
from pathlib import Path

import numpy as np
import yaml

sys.path.insert(0, str(Path(__file__).parents[2] / "experiments" / "bench"))
from open_planners import problem_yaml, schedule_paths, unsafe_steps  # noqa: E402


def test_the_problem_gives_every_robot_every_goal_cell_and_the_obstacles_in_our_axes():
    free = np.ones((5, 3), dtype=bool)
    free[2, 0] = free[4, 2] = False  # cells (x, y), as the lib's Location(x, y)
    starts, goals = np.array([[0, 0], [0, 2]]), np.array([[4, 0], [3, 2]])
    data = yaml.safe_load(yaml.safe_dump(problem_yaml(free, starts, goals)))
    assert data["map"] == {"dimensions": [5, 3], "obstacles": [[2, 0], [4, 2]]}
    assert [a["start"] for a in data["agents"]] == [[0, 0], [0, 2]]
    assert all(a["potentialGoals"] == [[4, 0], [3, 2]] for a in data["agents"])
    assert [a["name"] for a in data["agents"]] == ["agent0", "agent1"]


def test_a_schedule_becomes_paths_one_state_per_step_held_at_the_last_cell():
    # as ecbs_ta writes it: agent0 waits on a goal cell (free there, so its t, the cost so far, stands still at 1)
    # and moves on; its states are one per time step all the same
    text = """
schedule:
  agent0:
    - {x: 0, y: 0, t: 0}
    - {x: 1, y: 0, t: 1}
    - {x: 1, y: 0, t: 1}
    - {x: 2, y: 0, t: 2}
    - {x: 2, y: 1, t: 3}
  agent1:
    - {x: 0, y: 2, t: 0}
    - {x: 0, y: 1, t: 1}
"""
    paths = schedule_paths(yaml.safe_load(text)["schedule"], 2)
    assert paths.shape == (5, 2, 2)
    assert paths[:, 0].tolist() == [[0, 0], [1, 0], [1, 0], [2, 0], [2, 1]]
    assert paths[:, 1].tolist() == [[0, 2]] + [[0, 1]] * 4  # arrived at step 1, held after


def test_a_step_that_breaks_two_invariants_counts_once():
    free = np.ones((6, 6), dtype=bool)
    # step 1: robots 0 and 1 share a cell and come 0 cells close (two findings); step 2: they leave it, 0 cells close
    paths = np.array([[[0, 0], [2, 0], [1, 3]],
                      [[1, 0], [1, 0], [1, 3]],
                      [[2, 0], [1, 1], [1, 2]]])
    assert unsafe_steps(paths, free, 1.0) == 2
    assert unsafe_steps(paths[:1], free, 1.0) == 0
