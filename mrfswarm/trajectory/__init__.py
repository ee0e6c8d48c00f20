"""The continuous stage's engine: min-snap smoothing with pluggable solvers (paper Sec. IV-D).

Usable on its own, like the uav_trajectories tool:

>>> import numpy as np
>>> from mrfswarm.trajectory import constant_speed_durations, solve_min_snap, write_uav_csv
>>> W = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]])
>>> res = solve_min_snap(W, constant_speed_durations(W, 1.0))   # closed form, banded
>>> res = solve_min_snap(W, [1.0, 1.0], backend="osqp")          # the same QP, any backend  # doctest: +SKIP
>>> write_uav_csv(res.trajectory, "traj.csv", altitude=1.0)     # doctest: +SKIP

Modules, one job each:

- :mod:`~mrfswarm.trajectory.bernstein`: Bernstein control points of pieces and derivatives;
- :mod:`~mrfswarm.trajectory.polynomial`: :class:`PiecewisePolynomial` (evaluation,
  sampling, concatenation, time scaling) and the polynomial algebra;
- :mod:`~mrfswarm.trajectory.problem`: :class:`MinSnapProblem` (validated data, shape);
- :mod:`~mrfswarm.trajectory.formulation`: the CasADi formulation compiled per shape;
- :mod:`~mrfswarm.trajectory.banded`: the closed form, linear in the number of pieces;
- :mod:`~mrfswarm.trajectory.min_snap`: :func:`solve_min_snap`, :class:`MinSnapSolver`;
- :mod:`~mrfswarm.trajectory.corridor`, :mod:`~mrfswarm.trajectory.reference`:
  corridor boxes at sample times, tubes around reference motions;
- :mod:`~mrfswarm.trajectory.time_allocation`: initial durations and their refinement;
- :mod:`~mrfswarm.trajectory.retiming`: exact maxima, time scaling, toppra retiming
  (toppra's time law in :mod:`~mrfswarm.trajectory.toppra_law`, imported on use);
- :mod:`~mrfswarm.trajectory.uav_csv`, :mod:`~mrfswarm.trajectory.waypoints`: files.
"""

from mrfswarm.trajectory.banded import BandedSolution, solve_banded
from mrfswarm.trajectory.corridor import Corridor, corridor_sample_taus, corridor_sample_times, tube_corridor
from mrfswarm.trajectory.min_snap import (
    CLOSED_FORM,
    MinSnapBatchSolver,
    MinSnapResult,
    MinSnapSolver,
    min_snap_qp,
    solve_min_snap,
)
from mrfswarm.trajectory.polynomial import (
    PiecewisePolynomial,
    concatenate,
    integral_squared_derivative,
    seam_jumps,
)
from mrfswarm.trajectory.problem import MinSnapProblem, MinSnapShape
from mrfswarm.trajectory.reference import TIME_LAWS, PolylineReference, segment_reference, time_law
from mrfswarm.trajectory.retiming import (
    TimeScaling,
    ToppraRetiming,
    max_derivative_norm,
    max_derivative_norms,
    retime_toppra,
    scale_to_limits,
)
from mrfswarm.trajectory.time_allocation import (
    RefinedDurations,
    constant_speed_durations,
    cost_and_gradient,
    refine_durations,
    trapezoidal_durations,
)
from mrfswarm.trajectory.uav_csv import read_uav_csv, write_uav_csv
from mrfswarm.trajectory.waypoints import check_waypoints, read_waypoints_csv

__all__ = [
    "CLOSED_FORM",
    "TIME_LAWS",
    "BandedSolution",
    "Corridor",
    "MinSnapBatchSolver",
    "MinSnapProblem",
    "MinSnapResult",
    "MinSnapShape",
    "MinSnapSolver",
    "PiecewisePolynomial",
    "PolylineReference",
    "RefinedDurations",
    "TimeScaling",
    "ToppraRetiming",
    "check_waypoints",
    "concatenate",
    "constant_speed_durations",
    "corridor_sample_taus",
    "corridor_sample_times",
    "cost_and_gradient",
    "integral_squared_derivative",
    "max_derivative_norm",
    "max_derivative_norms",
    "min_snap_qp",
    "read_uav_csv",
    "read_waypoints_csv",
    "refine_durations",
    "retime_toppra",
    "scale_to_limits",
    "seam_jumps",
    "segment_reference",
    "solve_banded",
    "solve_min_snap",
    "time_law",
    "trapezoidal_durations",
    "tube_corridor",
    "write_uav_csv",
]
