"""mrfswarm: swarms of aerial robots planned by Markov random field optimization.

After Fernando & Liu, "Swarming of Aerial Robots with Markov Random Field Optimization".
The discrete stage moves the swarm over an occupancy grid with an MRF optimizer per
step; the continuous stage smooths the paths into min-snap trajectories solved by any
QP backend of :mod:`solvers.qp`, certified collision-free, and flown in simulation.

>>> import mrfswarm
>>> result = mrfswarm.plan(mrfswarm.load_config("experiments/corridor.toml"))  # doctest: +SKIP
>>> result.discrete.paths, result.continuous.trajectories, result.summary()    # doctest: +SKIP
"""

from mrfswarm.config import Config, load_config
from mrfswarm.discrete import DiscreteProblem, mrf_step, plan_discrete
from mrfswarm.errors import ConfigError, MrfswarmError, ScenarioError, SolverNotFound, UnsafeTrajectoryError
from mrfswarm.goal_distance import GoalDistance, goal_distance
from mrfswarm.interaction_graph import interaction_graph, knn_edges, maximal_cliques
from mrfswarm.maps import OccupancyGrid, load_map
from mrfswarm.pipeline import Result, plan
from mrfswarm.potentials import Morse, static_field
from mrfswarm.pruning import prune_paths
from mrfswarm.continuous import RecedingHorizon
from mrfswarm.robot_outcomes import RobotOutcome, robot_outcomes
from mrfswarm.safety import discrete_violations
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
