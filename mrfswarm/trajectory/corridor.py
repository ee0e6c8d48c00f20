"""Corridor constraints: boxes the position must stay in at sample times inside each piece.

Piece ``i`` (duration :math:`T_i`, start time :math:`t_i`) is sampled at ``K`` interior
points of normalized time

.. math::

    \\tau_s = \\frac{s + 1}{K + 1}, \\quad s = 0, \\dots, K-1, \\qquad
    t_{is} = t_i + \\tau_s T_i,

and the smoother imposes :math:`l_{is} \\le \\sigma(t_{is}) \\le u_{is}` componentwise. The
knots themselves are not sampled: the trajectory passes through the waypoints there.

In normalized time these rows do not depend on the durations (only their bounds do),
which keeps the formulation's constraint matrix fixed when only the waypoints or the
corridor move.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import cast

import numpy as np

from solvers.errors import InvalidProblem

Reference = Callable[[np.ndarray], np.ndarray]


def corridor_sample_taus(samples_per_piece: int) -> np.ndarray:
    """(K,) normalized sample times ``(s + 1) / (K + 1)`` inside a piece."""
    if samples_per_piece < 0:
        raise InvalidProblem(f"samples_per_piece must be >= 0, got {samples_per_piece}")
    return np.arange(1, samples_per_piece + 1) / (samples_per_piece + 1)


def corridor_sample_times(durations: np.ndarray, samples_per_piece: int, t0: float = 0.0) -> np.ndarray:
    """(M, K) global times of the corridor samples for pieces of ``durations`` starting at ``t0``.

    :math:`t_{is} = t_0 + \\sum_{j<i} T_j + \\tau_s T_i`.
    """
    T = np.asarray(durations, dtype=float).reshape(-1)
    starts = t0 + np.concatenate(([0.0], np.cumsum(T)[:-1]))
    return starts[:, None] + corridor_sample_taus(samples_per_piece)[None, :] * T[:, None]


@dataclass(frozen=True, eq=False)
class Corridor:
    """Per-sample boxes: ``lower[i, s] <= position(t_is) <= upper[i, s]``.

    Parameters
    ----------
    lower, upper
        (M, K, dim) bounds; ``-inf``/``inf`` leave a side free. ``K >= 1``.
    """

    lower: np.ndarray
    upper: np.ndarray

    def __post_init__(self) -> None:
        lo = np.array(self.lower, dtype=float)
        hi = np.array(self.upper, dtype=float)
        if lo.ndim != 3 or lo.shape != hi.shape or lo.shape[1] < 1:
            raise InvalidProblem(f"corridor bounds must both have shape (M, K>=1, dim), got {lo.shape} and {hi.shape}")
        if np.any(np.isnan(lo)) or np.any(np.isnan(hi)):
            raise InvalidProblem("corridor bounds must not contain NaN")
        if np.any(lo > hi):
            i, s, d = np.argwhere(lo > hi)[0]
            raise InvalidProblem(f"corridor lower bound exceeds upper bound at piece {i}, sample {s}, axis {d}")
        lo.setflags(write=False)
        hi.setflags(write=False)
        object.__setattr__(self, "lower", lo)
        object.__setattr__(self, "upper", hi)

    @property
    def pieces(self) -> int:
        """Number of pieces ``M``."""
        return self.lower.shape[0]

    @property
    def samples_per_piece(self) -> int:
        """Samples ``K`` per piece."""
        return self.lower.shape[1]

    @property
    def dim(self) -> int:
        """Spatial dimension."""
        return self.lower.shape[2]

    def violation(self, trajectory) -> float:
        """Largest bound violation of ``trajectory`` at the sample times (0 when inside)."""
        t = corridor_sample_times(trajectory.durations, self.samples_per_piece)
        p = trajectory.evaluate(t)
        return float(max(np.max(self.lower - p, initial=0.0), np.max(p - self.upper, initial=0.0)))


def evaluate_reference(reference: Reference | np.ndarray, times: np.ndarray, dim: int | None = None) -> np.ndarray:
    """Reference positions at ``times`` (any shape): ``times.shape + (dim,)``.

    ``reference`` is either a callable ``ref(t) -> (..., dim)``, called once on the whole
    array (vectorized; a callable that only takes scalars is called per time), or an
    array that already holds the positions at those times.
    """
    times = np.asarray(times, dtype=float)
    if callable(reference):
        try:
            out = np.asarray(reference(times), dtype=float)
            if out.shape[:-1] != times.shape:
                raise ValueError
        except (ValueError, TypeError, IndexError):
            scalar_ref = cast(Callable[[float], np.ndarray], reference)  # it takes scalars only
            out = np.array([np.asarray(scalar_ref(float(t)), dtype=float) for t in times.reshape(-1)])
            out = out.reshape(times.shape + (-1,))
    else:
        out = np.asarray(reference, dtype=float)
        if out.shape[:-1] != times.shape:
            raise InvalidProblem(f"reference array has shape {out.shape}, expected {times.shape} + (dim,)")
    if dim is not None and out.shape[-1] != dim:
        raise InvalidProblem(f"reference has dimension {out.shape[-1]}, expected {dim}")
    if not np.all(np.isfinite(out)):
        raise InvalidProblem("reference positions must be finite")
    return out


def tube_corridor(
    reference: Reference | np.ndarray,
    durations: np.ndarray,
    samples_per_piece: int,
    half_width: float | np.ndarray,
    t0: float = 0.0,
) -> Corridor:
    """An L-infinity tube of half-width ``r`` around a reference motion, as per-sample boxes.

    .. math::

        \\mathrm{ref}(t_{is}) - r \\le \\sigma(t_{is}) \\le \\mathrm{ref}(t_{is}) + r

    Parameters
    ----------
    reference
        Callable ``ref(t)`` on an array of global times returning ``(..., dim)``, or an
        (M, K, dim) array of positions at :func:`corridor_sample_times` ``(durations, K, t0)``.
    durations
        (M,) piece durations.
    samples_per_piece
        ``K >= 1``.
    half_width
        Scalar, or (dim,) per-axis half-widths, > 0.
    t0
        Global time at which the trajectory starts (pieces of a later receding-horizon
        window sample the common time grid from there).
    """
    if samples_per_piece < 1:
        raise InvalidProblem(f"a tube corridor needs samples_per_piece >= 1, got {samples_per_piece}")
    r = np.asarray(half_width, dtype=float)
    if not np.all(np.isfinite(r)) or np.any(r <= 0):
        raise InvalidProblem(f"tube half-width must be positive and finite, got {half_width}")
    times = corridor_sample_times(durations, samples_per_piece, t0)
    ref = evaluate_reference(reference, times)
    return Corridor(ref - r, ref + r)
