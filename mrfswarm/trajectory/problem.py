"""The minimum-derivative (min-snap) smoothing problem: its data, validated, and its shape.

Find ``M`` polynomial pieces of degree ``D`` through waypoints :math:`w_0, \\dots, w_M`
with durations :math:`T_i` that minimize

.. math::

    J = \\int_0^{\\sum T_i} \\|\\sigma^{(q)}(t)\\|^2 dt \\qquad (q = 4: \\text{snap})

subject to

- waypoints: :math:`\\sigma(t_i) = w_i` for every knot;
- continuity of derivatives :math:`1, \\dots, c` at the interior knots (default
  :math:`c = q - 1`: velocity, acceleration and jerk for min-snap, as the paper);
- end conditions at each end: derivatives :math:`1, \\dots, k` given (``"rest"`` =
  all of :math:`1, \\dots, q-1` zero, the default), or ``"free"`` (:math:`k = 0`);
- optionally a :class:`~mrfswarm.trajectory.corridor.Corridor`: position boxes at
  sample times inside each piece.

The *shape* (:class:`MinSnapShape`) is everything that fixes the structure of the
quadratic program; the waypoints, durations, corridor bounds and end derivatives are
its parameters.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mrfswarm.trajectory.corridor import Corridor
from solvers.errors import InvalidProblem

#: The paper's piece degree (7) and minimized derivative (4, snap), the defaults of every
#: smoothing function, the config and ``mrfswarm smooth``: degree ``2q - 1``, the lowest the
#: closed form takes, and the highest the uav_trajectories CSV holds.
DEFAULT_DEGREE = 7
DEFAULT_DERIVATIVE = 4

EndSpec = str | np.ndarray | list | tuple | None


@dataclass(frozen=True)
class MinSnapShape:
    """What the compiled formulation depends on (and is cached by).

    Attributes
    ----------
    pieces, dim, degree, derivative
        ``M``, spatial dimension, polynomial degree ``D``, minimized derivative ``q``.
    continuity
        Highest derivative order continuous at interior knots.
    samples_per_piece
        Corridor samples ``K`` per piece (0: no corridor).
    start_order, end_order
        Number of derivatives (1..k) given at each end (0: free end).
    """

    pieces: int
    dim: int
    degree: int
    derivative: int
    continuity: int
    samples_per_piece: int
    start_order: int
    end_order: int

    @property
    def n_variables(self) -> int:
        """``dim * M * (D + 1)`` polynomial coefficients."""
        return self.dim * self.pieces * (self.degree + 1)


def _end_derivatives(spec: EndSpec, dim: int, q: int, which: str) -> np.ndarray:
    if spec is None or (isinstance(spec, str) and spec == "rest"):
        return np.zeros((q - 1, dim))
    if isinstance(spec, str):
        if spec == "free":
            return np.zeros((0, dim))
        raise InvalidProblem(f"{which} must be 'rest', 'free' or an array of derivatives 1..k, got {spec!r}")
    g = np.array(spec, dtype=float)
    if g.ndim == 1:
        g = g[None, :]
    if g.ndim != 2 or g.shape[1] != dim:
        raise InvalidProblem(f"{which} derivatives must have shape (k, {dim}) (rows: derivative 1, 2, ...), got {g.shape}")
    if g.shape[0] > q - 1:
        raise InvalidProblem(f"{which} gives {g.shape[0]} derivatives; at most q - 1 = {q - 1} can be fixed")
    if not np.all(np.isfinite(g)):
        raise InvalidProblem(f"{which} derivatives must be finite")
    return g


class MinSnapProblem:
    """Validated data of one smoothing problem.

    Parameters
    ----------
    waypoints
        (M+1, dim) positions, ``dim >= 1`` (2 or 3 in practice).
    durations
        (M,) positive piece durations (seconds).
    degree
        Polynomial degree ``D >= 2q - 1`` (default 7).
    derivative
        Minimized derivative ``q >= 1`` (default 4, snap; 3 is jerk).
    continuity
        Highest derivative continuous at interior knots, ``q - 1 <= c <= D - 1``
        (lower orders would leave the optimum non-unique); ``None`` means ``q - 1``.
    start, end
        ``"rest"`` (derivatives 1..q-1 zero, default), ``"free"``, or a (k, dim)
        array of derivatives 1..k at that end (``k <= q - 1``; a (dim,) vector is
        a velocity).
    corridor
        Optional per-sample position boxes for these pieces.
    waypoint_tolerance
        Optional (M+1,) or (M+1, dim) non-negative half-widths: knot j may lie anywhere in
        the box ``waypoints[j] +- tolerance[j]`` instead of exactly on it (0 keeps it
        exact). ``None`` (or all zeros) means every waypoint is exact. A tolerance turns
        the waypoint rows into inequalities, so it needs a QP backend.

    Raises
    ------
    InvalidProblem
        For any malformed value; the message names it.
    """

    def __init__(
        self,
        waypoints: np.ndarray,
        durations: np.ndarray,
        *,
        degree: int = DEFAULT_DEGREE,
        derivative: int = DEFAULT_DERIVATIVE,
        continuity: int | None = None,
        start: EndSpec = "rest",
        end: EndSpec = "rest",
        corridor: Corridor | None = None,
        waypoint_tolerance: np.ndarray | None = None,
    ) -> None:
        W = np.array(waypoints, dtype=float)
        if W.ndim != 2 or W.shape[0] < 2 or W.shape[1] < 1:
            raise InvalidProblem(f"waypoints must have shape (M+1 >= 2, dim), got {W.shape}")
        if not np.all(np.isfinite(W)):
            i = int(np.argwhere(~np.isfinite(W))[0, 0])
            raise InvalidProblem(f"waypoint {i} is not finite: {W[i].tolist()}")
        M, dim = W.shape[0] - 1, W.shape[1]
        T = np.array(durations, dtype=float).reshape(-1)
        if T.size != M:
            raise InvalidProblem(f"{T.size} durations given for {M} pieces ({M + 1} waypoints)")
        bad = ~(np.isfinite(T) & (T > 0))
        if np.any(bad):
            i = int(np.argmax(bad))
            raise InvalidProblem(f"durations must be positive and finite; duration {i} is {T[i]}")
        q = int(derivative)
        if q < 1:
            raise InvalidProblem(f"minimized derivative must be >= 1, got {derivative}")
        D = int(degree)
        if D < 2 * q - 1:
            raise InvalidProblem(f"degree {D} is too low: minimizing derivative {q} needs degree >= 2q - 1 = {2 * q - 1}")
        c = q - 1 if continuity is None else int(continuity)
        if not q - 1 <= c <= D - 1:
            # below q - 1 a piecewise polynomial of degree < q could be added at no cost: no unique optimum
            raise InvalidProblem(f"continuity order must be in q-1..degree-1 = {q - 1}..{D - 1}, got {c}")
        g0 = _end_derivatives(start, dim, q, "start")
        g1 = _end_derivatives(end, dim, q, "end")
        if corridor is not None:
            if not isinstance(corridor, Corridor):
                raise InvalidProblem(f"corridor must be a Corridor, got {type(corridor).__name__}")
            if corridor.pieces != M or corridor.dim != dim:
                raise InvalidProblem(
                    f"corridor has {corridor.pieces} pieces in {corridor.dim}-D, the problem {M} pieces in {dim}-D"
                )
        tol = None
        if waypoint_tolerance is not None:
            tol = np.array(waypoint_tolerance, dtype=float)
            if tol.ndim == 1:
                tol = np.repeat(tol[:, None], dim, axis=1)
            if tol.shape != (M + 1, dim):
                raise InvalidProblem(f"waypoint_tolerance must have shape ({M + 1},) or ({M + 1}, {dim}), got {tol.shape}")
            if not np.all(np.isfinite(tol)) or np.any(tol < 0):
                raise InvalidProblem("waypoint_tolerance must be finite and >= 0")
            if not np.any(tol > 0):
                tol = None
            else:
                tol.setflags(write=False)
        for a in (W, T, g0, g1):
            a.setflags(write=False)
        self.waypoint_tolerance = tol
        self.waypoints, self.durations = W, T
        self.degree, self.derivative, self.continuity = D, q, c
        self.start, self.end, self.corridor = g0, g1, corridor
        self.shape = MinSnapShape(
            pieces=M, dim=dim, degree=D, derivative=q, continuity=c,
            samples_per_piece=0 if corridor is None else corridor.samples_per_piece,
            start_order=g0.shape[0], end_order=g1.shape[0],
        )

    @property
    def pieces(self) -> int:
        """Number of pieces ``M``."""
        return self.shape.pieces

    @property
    def dim(self) -> int:
        """Spatial dimension."""
        return self.shape.dim

    @property
    def has_corridor(self) -> bool:
        """True when corridor inequalities are part of the problem."""
        return self.corridor is not None

    def with_data(self, waypoints: np.ndarray | None = None, durations: np.ndarray | None = None,
                  corridor: Corridor | None = None) -> MinSnapProblem:
        """A problem of the same settings with new waypoints, durations and/or corridor."""
        return MinSnapProblem(
            self.waypoints if waypoints is None else waypoints,
            self.durations if durations is None else durations,
            degree=self.degree, derivative=self.derivative, continuity=self.continuity,
            start=self.start, end=self.end, corridor=self.corridor if corridor is None else corridor,
            waypoint_tolerance=self.waypoint_tolerance,
        )
