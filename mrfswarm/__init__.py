"""mrfswarm: swarms of aerial robots planned by Markov random field optimization.

After Fernando & Liu, "Swarming of Aerial Robots with Markov Random Field Optimization".
The discrete stage (:mod:`mrfswarm.discrete`) moves the swarm over an occupancy grid with
an MRF optimizer per step; the continuous stage (:mod:`mrfswarm.continuous`) flies every
robot through safe regions derived from those moves, on QPs solved by any backend of
:mod:`solvers.qp`, certified exactly, then flown in simulation (:mod:`mrfswarm.simulation`).
:func:`plan` runs both (:mod:`mrfswarm.pipeline`); the repository's ``docs/`` describe it.

>>> import mrfswarm
>>> result = mrfswarm.plan(mrfswarm.load_config("experiments/corridor.toml"))  # doctest: +SKIP
>>> result.discrete.paths, result.continuous.trajectories, result.summary()    # doctest: +SKIP
"""

from mrfswarm.config import Config, load_config
from mrfswarm.continuous import RecedingHorizon
from mrfswarm.discrete import (
    DiscreteProblem,
    GoalDistance,
    Morse,
    RobotOutcome,
    discrete_violations,
    goal_distance,
    interaction_graph,
    knn_edges,
    maximal_cliques,
    mrf_step,
    plan_discrete,
    prune_paths,
    robot_outcomes,
    static_field,
)
from mrfswarm.errors import ConfigError, MrfswarmError, PlanError, ScenarioError, SolverNotFound, UnsafeTrajectoryError
from mrfswarm.maps import OccupancyGrid, load_map
from mrfswarm.pipeline import Result, plan
from mrfswarm.scenario import Scenario, build_scenario

__version__ = "0.1.0"

__all__ = [
    "Config",
    "ConfigError",
    "DiscreteProblem",
    "GoalDistance",
    "Morse",
    "MrfswarmError",
    "OccupancyGrid",
    "PlanError",
    "RecedingHorizon",
    "Result",
    "RobotOutcome",
    "Scenario",
    "ScenarioError",
    "SolverNotFound",
    "UnsafeTrajectoryError",
    "build_scenario",
    "discrete_violations",
    "goal_distance",
    "interaction_graph",
    "knn_edges",
    "load_config",
    "load_map",
    "maximal_cliques",
    "mrf_step",
    "plan",
    "plan_discrete",
    "prune_paths",
    "robot_outcomes",
    "static_field",
]
