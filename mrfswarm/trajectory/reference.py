"""Reference motions for corridors: straight segments traversed with a time law.

A segment from ``a`` to ``b`` over ``[t0, t1]`` with time law ``s`` is

.. math::

    \\mathrm{ref}(t) = a + s\\!\\left(\\frac{t - t_0}{t_1 - t_0}\\right) (b - a),

clamped to ``a`` before ``t0`` and ``b`` after ``t1``. The time laws map [0, 1] onto
[0, 1] monotonically:

- ``linear``: :math:`s(\\tau) = \\tau` (constant speed, what a robot of the discrete
  stage does between two grid steps);
- ``quintic``: :math:`10\\tau^3 - 15\\tau^4 + 6\\tau^5`, at rest up to acceleration at both
  ends (the one-piece minimum-jerk law);
- ``smooth``: :math:`35\\tau^4 - 84\\tau^5 + 70\\tau^6 - 20\\tau^7`, at rest up to jerk at
  both ends (the one-piece minimum-snap law).

A polyline through points at given times (a robot's discrete motion on the swarm's
common time grid) chains such segments.
"""

from __future__ import annotations

import numpy as np

from solvers.errors import InvalidProblem

#: name -> ascending power coefficients of s(tau)
TIME_LAWS: dict[str, tuple[float, ...]] = {
    "linear": (0.0, 1.0),
    "quintic": (0.0, 0.0, 0.0, 10.0, -15.0, 6.0),
    "smooth": (0.0, 0.0, 0.0, 0.0, 35.0, -84.0, 70.0, -20.0),
}


def time_law(name: str):
    """The vectorized time law ``s(tau)`` called ``name`` (tau clamped to [0, 1]).

    Raises
    ------
    InvalidProblem
        For an unknown name; the message lists the known ones.
    """
    try:
        coeffs = np.array(TIME_LAWS[name])
    except KeyError:
        raise InvalidProblem(f"unknown time law {name!r}; known: {', '.join(TIME_LAWS)}") from None

    def s(tau: np.ndarray) -> np.ndarray:
        return np.polynomial.polynomial.polyval(np.clip(tau, 0.0, 1.0), coeffs)

    return s


class PolylineReference:
    """Straight segments between ``points`` reached at ``times``, each with the same time law.

    Parameters
    ----------
    points
        (S+1, dim) positions.
    times
        (S+1,) strictly increasing times at which the points are reached.
    law
        A name of :data:`TIME_LAWS`.

    Calling the object with an array of times returns ``times.shape + (dim,)``
    positions; before the first time it holds the first point, after the last the last.
    """

    def __init__(self, points: np.ndarray, times: np.ndarray, law: str = "linear") -> None:
        P = np.asarray(points, dtype=float)
        t = np.asarray(times, dtype=float).reshape(-1)
        if P.ndim != 2 or P.shape[0] < 2 or t.shape != (P.shape[0],):
            raise InvalidProblem(f"need (S+1, dim) points with S >= 1 and (S+1,) times, got {P.shape} and {t.shape}")
        if not (np.all(np.isfinite(P)) and np.all(np.isfinite(t))):
            raise InvalidProblem("reference points and times must be finite")
        if np.any(np.diff(t) <= 0):
            raise InvalidProblem("reference times must be strictly increasing")
        self.points, self.times, self.law = P, t, law
        self._s = time_law(law)

    def __call__(self, t: np.ndarray | float) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        j = np.clip(np.searchsorted(self.times, t, side="right") - 1, 0, len(self.times) - 2)
        tau = (t - self.times[j]) / (self.times[j + 1] - self.times[j])
        s = self._s(tau)[..., None]
        return self.points[j] + s * (self.points[j + 1] - self.points[j])


def segment_reference(a: np.ndarray, b: np.ndarray, t0: float, t1: float, law: str = "linear") -> PolylineReference:
    """The motion from ``a`` to ``b`` over ``[t0, t1]`` with time law ``law`` (see module doc)."""
    return PolylineReference(np.vstack([np.asarray(a, float), np.asarray(b, float)]), np.array([t0, t1], float), law)
