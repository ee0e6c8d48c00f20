"""Step 2 of :func:`~mrfswarm.trajectory.retiming.retime_toppra`: toppra's time law on a path.

This module imports toppra at its top: import it only after
:func:`~mrfswarm.trajectory.retiming.require_toppra` (toppra is an optional extra).
"""

from __future__ import annotations

import numpy as np
import toppra
import toppra.algorithm as algo
import toppra.constraint as constraint

from mrfswarm.trajectory.polynomial import PiecewisePolynomial
from mrfswarm.trajectory.retiming import SD_BOUND
from solvers.errors import SolverError


class PolynomialPath(toppra.interpolator.AbstractGeometricPath):
    """A piecewise polynomial as toppra's geometric path (its parameter: the polynomial's time)."""

    def __init__(self, path: PiecewisePolynomial) -> None:
        self._path = path

    def __call__(self, path_positions, order=0):
        return self._path.evaluate(path_positions, order)

    @property
    def dof(self):
        return self._path.dim

    @property
    def path_interval(self):
        return np.array([0.0, self._path.duration])


class RateBound(constraint.LinearConstraint):
    """``sd <= SD_BOUND``; at the rest ends nothing else bounds it."""

    def __init__(self, dim: int) -> None:
        super().__init__()
        self.dof = dim

    def compute_constraint_params(self, _path, gridpoints):
        xb = np.zeros((len(gridpoints), 2))
        xb[:, 1] = SD_BOUND**2
        return None, None, None, None, None, None, xb


def limits_constraint(dim: int, v_max: float, a_max: float, directions: np.ndarray, h: float):
    """``|qd|^2 <= v_max^2`` and ``directions @ qdd <= h a_max`` as toppra's second-order constraint.

    ``w = (|qd|^2, qdd)`` is linear in ``(sdd, sd^2)`` along the path, as that form needs.
    """
    F = np.zeros((1 + len(directions), 1 + dim))
    F[0, 0] = 1.0
    F[1:, 1:] = directions
    g = np.concatenate([[v_max**2], np.full(len(directions), h * a_max)])
    return constraint.SecondOrderConstraint(
        lambda q, qd, qdd: np.concatenate([[qd @ qd], qdd]), lambda q: F, lambda q: g, dof=dim,
        discretization_scheme=constraint.DiscretizationType.Interpolation,
    )


def time_optimal_law(path: PiecewisePolynomial, grid: np.ndarray, v_max: float, a_max: float,
                     directions: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """toppra's time-optimal law on ``path`` at ``grid``: ``(s, sd, t)`` per gridpoint, rest to rest.

    Raises
    ------
    SolverError
        toppra fails, or returns a law that is not strictly increasing in time.
    """
    con = limits_constraint(path.dim, v_max, a_max, directions, h)
    inst = algo.TOPPRA([con, RateBound(path.dim)], PolynomialPath(path), gridpoints=grid, solver_wrapper="seidel")
    inst.compute_parameterization(0.0, 0.0)
    data = inst.problem_data
    if data.return_code != algo.ParameterizationReturnCode.Ok or data.sd_vec is None:
        raise SolverError(f"toppra failed to parametrize the path: {data.return_code}", backend="toppra",
                          status=str(data.return_code))
    sd = np.asarray(data.sd_vec, dtype=float).reshape(-1)
    ss = np.asarray(data.gridpoints, dtype=float).reshape(-1)
    dt = 2.0 * np.diff(ss) / np.maximum(sd[:-1] + sd[1:], 1e-300)  # constant path acceleration per interval
    times = np.concatenate([[0.0], np.cumsum(dt)])
    if ss.size != grid.size or not np.all(np.isfinite(times)) or np.any(dt <= 0):
        raise SolverError("toppra returned an unusable parametrization", backend="toppra", status="bad_time_law")
    return ss, sd, times
