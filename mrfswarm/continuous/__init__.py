"""The continuous stage: smooth flights in safe regions derived from the discrete plan.

Modules, one part each:

- :mod:`~mrfswarm.continuous.regions`: obstacle-free regions per robot and step, relative
  safe corridors per pair of robots, interaction groups;
- :mod:`~mrfswarm.trajectory.bernstein`: control points of pieces and their derivatives;
- :mod:`~mrfswarm.continuous.formulation`: the window problem, formulated once with
  CasADi, as a QP (fixed durations) or an NLP (durations as variables);
- :mod:`~mrfswarm.continuous.time_grid`: nominal and witness step durations;
- :mod:`~mrfswarm.continuous.certificate`: the exact certificate of a flight;
- :mod:`~mrfswarm.continuous.receding_horizon`: the window loop;
- :mod:`~mrfswarm.continuous.sampled_check`: the optional dense sampled check (independent
  of the certificate).

The dimension is data: discrete paths of shape (T + 1, N, d) on a grid of d = 2 or 3 axes
give trajectories of d coordinates, by the same code. Separation is measured and
constrained in the downwash-scaled metric ``|| (p - q) * geometry.downwash_scale(d, c) ||``
(``scenario.downwash`` = c, passed as ``RecedingHorizon(..., downwash=c)``; the identity
in the plane), so :attr:`ContinuousPlan.min_separation` is the scaled minimum (also named
``min_separation_scaled``); obstacle clearance is the plain distance to occupied cells or
voxels.
"""

from mrfswarm.continuous.certificate import Certificate, certify, hull_distance_from_origin
from mrfswarm.continuous.formulation import WindowFormulation, WindowSpec
from mrfswarm.continuous.receding_horizon import ContinuousPlan, RecedingHorizon, WindowRecord
from mrfswarm.continuous.regions import Regions, Separations, build_regions, region_clearance, separations

__all__ = [
    "Certificate",
    "ContinuousPlan",
    "RecedingHorizon",
    "Regions",
    "Separations",
    "WindowFormulation",
    "WindowRecord",
    "WindowSpec",
    "build_regions",
    "certify",
    "hull_distance_from_origin",
    "region_clearance",
    "separations",
]
