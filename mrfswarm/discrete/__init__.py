"""The discrete stage: the swarm moves over the grid, one MRF optimization per step.

The grid has d = 2 or 3 axes (voxels); cells are integer arrays of shape (..., d) and
every module works on either by the same lines. On voxels, ``downwash`` = c keeps every
pair of robots one cell apart in the scaled metric of
:func:`mrfswarm.geometry.downwash_scale` (at steps and along moves).

Modules, in the order data flows through them:

- :mod:`~mrfswarm.discrete.start`: the start cells (explicit, or sampled as the paper does);
- :mod:`~mrfswarm.discrete.goal_distance`: the free-path (geodesic) distance to the goal;
- :mod:`~mrfswarm.discrete.potentials`: the static field rho_S (goal + obstacles) and the
  Morse interaction rho_D, with the paper's parameter conditions;
- :mod:`~mrfswarm.discrete.interaction_graph`: the k-nearest-neighbour graph, its maximal
  cliques and their pairwise reduction;
- :mod:`~mrfswarm.discrete.motion`: the move stencil and the motion rules (distances
  during a move, wall clearance);
- :mod:`~mrfswarm.discrete.label_sets`: each robot's candidate cells X_i^t, disjoint;
- :mod:`~mrfswarm.discrete.step_mrf`: one step's pairwise MRF (unary, pairwise, conflicts);
- :mod:`~mrfswarm.discrete.planner`: the loop of MRF steps and its stop rules;
- :mod:`~mrfswarm.discrete.safety`: the discrete safety invariant, checked on every plan;
- :mod:`~mrfswarm.discrete.robot_outcomes`: where each robot ended and why;
- :mod:`~mrfswarm.discrete.pruning`: the paper's waypoint pruning of the paths.
"""

from mrfswarm.discrete.goal_distance import GoalDistance, goal_distance
from mrfswarm.discrete.interaction_graph import CliqueWeights, interaction_graph, knn_edges, maximal_cliques
from mrfswarm.discrete.label_sets import LabelSets, label_sets
from mrfswarm.discrete.planner import (
    DiscretePlan,
    DiscreteProblem,
    StepOutcome,
    mrf_step,
    plan_discrete,
    step_model,
    swarm_energy,
)
from mrfswarm.discrete.potentials import Morse, static_field
from mrfswarm.discrete.pruning import prune_paths
from mrfswarm.discrete.robot_outcomes import RobotOutcome, robot_outcomes
from mrfswarm.discrete.safety import discrete_violations
from mrfswarm.discrete.step_mrf import step_mrf

__all__ = [
    "CliqueWeights",
    "DiscretePlan",
    "DiscreteProblem",
    "GoalDistance",
    "LabelSets",
    "Morse",
    "RobotOutcome",
    "StepOutcome",
    "discrete_violations",
    "goal_distance",
    "interaction_graph",
    "knn_edges",
    "label_sets",
    "maximal_cliques",
    "mrf_step",
    "plan_discrete",
    "prune_paths",
    "robot_outcomes",
    "static_field",
    "step_mrf",
    "step_model",
    "swarm_energy",
]
