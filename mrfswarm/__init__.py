"""mrfswarm: swarms of aerial robots planned by Markov random field optimization.

After Fernando & Liu, "Swarming of Aerial Robots with Markov Random Field Optimization".
The discrete stage moves the swarm over an occupancy grid with an MRF optimizer per
step; the continuous stage smooths the paths into min-snap trajectories solved by any
QP backend of :mod:`solvers.qp`.
"""

from mrfswarm.config import Config, load_config
from mrfswarm.errors import ConfigError, MrfswarmError, ScenarioError, SolverNotFound, UnsafeTrajectoryError

__version__ = "0.1.0"

__all__ = [
    "Config",
    "ConfigError",
    "MrfswarmError",
    "ScenarioError",
    "SolverNotFound",
    "UnsafeTrajectoryError",
    "load_config",
]
