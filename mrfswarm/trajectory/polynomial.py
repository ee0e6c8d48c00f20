"""Piecewise polynomial trajectories and the polynomial algebra the smoother needs.

A trajectory of ``M`` pieces in ``dim`` dimensions is

.. math::

    \\sigma(t) = \\sum_{k=0}^{D} a_{ik} (t - t_i)^k, \\qquad t \\in [t_i, t_{i+1}],
    \\quad t_{i+1} = t_i + T_i,

with durations ``T`` (M,) and coefficients ``a`` (M, D+1, dim) in increasing power of
the piece's local time (the uav_trajectories / Crazyswarm convention).

The optimizer works with coefficients in *normalized* local time
:math:`\\tau = (t - t_i) / T_i \\in [0, 1]`: :math:`c_{ik} = a_{ik} T_i^k`, which keeps
every coefficient in position units whatever the duration.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
from scipy.special import comb

from solvers.errors import InvalidProblem, real_array


@lru_cache(maxsize=64)
def falling_factorials(degree: int, order: int) -> np.ndarray:
    """``k! / (k - order)!`` for ``k = 0..degree`` (0 where ``k < order``).

    The factor by which the ``order``-th derivative of :math:`t^k` is
    :math:`t^{k - order}`. Read-only array.
    """
    k = np.arange(degree + 1)
    out = np.ones(degree + 1)
    for j in range(order):
        out *= k - j
    out[k < order] = 0.0
    out.setflags(write=False)
    return out


@lru_cache(maxsize=64)
def derivative_row(degree: int, order: int, tau: float) -> np.ndarray:
    """Row ``r`` with ``r @ c`` = the ``order``-th tau-derivative at ``tau`` of :math:`\\sum_k c_k \\tau^k`.

    ``r_k = k!/(k-order)! * tau^(k-order)`` for ``k >= order``, else 0. Read-only.
    """
    k = np.arange(degree + 1)
    f = falling_factorials(degree, order)
    powers = np.where(k >= order, k - order, 0)
    out = f * float(tau) ** powers
    out.setflags(write=False)
    return out


@lru_cache(maxsize=64)
def cost_hessian(degree: int, order: int) -> np.ndarray:
    """Gram matrix of the ``order``-th derivative of the monomials on [0, 1].

    .. math::

        H_{jk} = \\int_0^1 \\frac{d^q \\tau^j}{d\\tau^q} \\frac{d^q \\tau^k}{d\\tau^q} d\\tau
               = \\frac{j!}{(j-q)!} \\frac{k!}{(k-q)!} \\frac{1}{j + k - 2q + 1},
        \\quad j, k \\ge q,

    and 0 otherwise, so that :math:`\\int_0^T \\|\\sigma^{(q)}(t)\\|^2 dt = T^{1-2q} c^\\top H c`
    for a piece of duration ``T`` with tau-coefficients ``c``. Read-only.
    """
    k = np.arange(degree + 1)
    f = falling_factorials(degree, order)
    denom = k[:, None] + k[None, :] - 2 * order + 1
    with np.errstate(divide="ignore", invalid="ignore"):
        H = np.where((k[:, None] >= order) & (k[None, :] >= order), np.outer(f, f) / denom, 0.0)
    H.setflags(write=False)
    return H


def tau_to_time(coefficients: np.ndarray, durations: np.ndarray) -> np.ndarray:
    """Convert tau-coefficients ``c`` (M, D+1, dim) to local-time coefficients ``a = c / T^k``."""
    k = np.arange(coefficients.shape[1])
    return coefficients / durations[:, None, None] ** k[None, :, None]


def time_to_tau(coefficients: np.ndarray, durations: np.ndarray) -> np.ndarray:
    """Convert local-time coefficients ``a`` (M, D+1, dim) to tau-coefficients ``c = a T^k``."""
    k = np.arange(coefficients.shape[1])
    return coefficients * durations[:, None, None] ** k[None, :, None]


@dataclass(frozen=True, eq=False)
class PiecewisePolynomial:
    """A piecewise polynomial trajectory starting at time 0.

    Parameters
    ----------
    durations
        (M,) positive finite piece durations :math:`T_i` (seconds).
    coefficients
        (M, D+1, dim) coefficients :math:`a_{ik}` in increasing power of the piece's
        local time :math:`t - t_i`.

    Notes
    -----
    Evaluation outside ``[0, duration]`` clamps the time to that interval (the
    trajectory holds its end state's polynomial value; for a trajectory at rest at its
    ends this is hovering).
    """

    durations: np.ndarray
    coefficients: np.ndarray
    _knots: np.ndarray = field(init=False, repr=False)  # 0 and the cumulative durations, set in __post_init__

    def __post_init__(self) -> None:
        T = np.array(real_array(self.durations, "durations")).reshape(-1)  # copies: the trajectory owns them
        a = np.array(real_array(self.coefficients, "coefficients"))
        if a.ndim == 2:  # one dimension given as (M, D+1)
            a = a[:, :, None]
        if a.ndim != 3 or a.shape[0] != T.size or a.shape[0] == 0 or a.shape[2] == 0:
            raise InvalidProblem(
                f"coefficients must have shape (M, degree+1, dim) with M = {T.size} durations, got {a.shape}"
            )
        if not np.all(np.isfinite(T)) or np.any(T <= 0):
            i = int(np.argmax(~(np.isfinite(T) & (T > 0))))
            raise InvalidProblem(f"durations must be positive and finite; duration {i} is {T[i]}")
        if not np.all(np.isfinite(a)):
            raise InvalidProblem("trajectory coefficients must be finite (found NaN or inf)")
        T.setflags(write=False)
        a.setflags(write=False)
        object.__setattr__(self, "durations", T)
        object.__setattr__(self, "coefficients", a)
        object.__setattr__(self, "_knots", np.concatenate(([0.0], np.cumsum(T))))

    # ----------------------------------------------------------------- shape
    @property
    def pieces(self) -> int:
        """Number of pieces ``M``."""
        return self.durations.size

    @property
    def degree(self) -> int:
        """Polynomial degree ``D`` (the coefficient array's length minus one)."""
        return self.coefficients.shape[1] - 1

    @property
    def dim(self) -> int:
        """Spatial dimension."""
        return self.coefficients.shape[2]

    @property
    def duration(self) -> float:
        """Total duration :math:`\\sum_i T_i`."""
        return float(self._knots[-1])

    @property
    def knots(self) -> np.ndarray:
        """(M+1,) piece start times and the end time, ``[0, T_0, T_0 + T_1, ...]``."""
        return self._knots.copy()

    # ------------------------------------------------------------ evaluation
    def piece_index(self, t: np.ndarray) -> np.ndarray:
        """Index of the piece holding each time of ``t`` (after clamping to ``[0, duration]``)."""
        t = np.clip(np.asarray(t, dtype=float), 0.0, self.duration)
        return np.clip(np.searchsorted(self._knots, t, side="right") - 1, 0, self.pieces - 1)

    def __call__(self, t: float | np.ndarray, derivative: int = 0) -> np.ndarray:
        """Alias of :meth:`evaluate`."""
        return self.evaluate(t, derivative)

    def evaluate(self, t: float | np.ndarray, derivative: int = 0) -> np.ndarray:
        """The ``derivative``-th time derivative at times ``t``.

        Parameters
        ----------
        t
            Times (s, any shape); clamped to ``[0, duration]``.
        derivative
            Order of the derivative, 0 for position.

        Returns
        -------
        numpy.ndarray
            Shape ``t.shape + (dim,)``.

        Raises
        ------
        InvalidProblem
            A time that is NaN or not a number (NaN gave NaN without a word), a derivative order that is not
            an integer >= 0 (1.5 ended in "slice indices must be integers"; a library tour).
        """
        _check_order(derivative)
        t = t if isinstance(t, np.ndarray) and t.dtype.kind == "f" else real_array(t, "t")
        if np.isnan(t).any():
            raise InvalidProblem(f"t must not be NaN, got {t.tolist()!s:.60}")
        shape = t.shape
        tf = np.clip(t.reshape(-1), 0.0, self.duration)
        if derivative > self.degree:
            return np.zeros(shape + (self.dim,))
        idx = np.clip(np.searchsorted(self._knots, tf, side="right") - 1, 0, self.pieces - 1)
        s = (tf - self._knots[idx])[:, None]
        a = self.coefficients[:, derivative:, :] * falling_factorials(self.degree, derivative)[derivative:, None]
        a = a[idx]  # (n, D+1-r, dim)
        out = a[:, -1, :].copy()
        for k in range(a.shape[1] - 2, -1, -1):  # Horner
            out *= s
            out += a[:, k, :]
        return out.reshape(shape + (self.dim,))

    def sample(self, rate: float) -> tuple[np.ndarray, np.ndarray]:
        """Positions sampled at ``rate`` Hz from 0, plus the end time.

        Returns
        -------
        times : numpy.ndarray
            (n,) sample times, ``k / rate`` and the final time.
        positions : numpy.ndarray
            (n, dim).
        """
        if not (np.isfinite(rate) and rate > 0):
            raise InvalidProblem(f"sampling rate must be positive, got {rate}")
        n = int(np.floor(self.duration * rate + 1e-9)) + 1
        t = np.arange(n) / rate
        if t[-1] < self.duration - 1e-12:
            t = np.append(t, self.duration)
        return t, self.evaluate(t)

    # ----------------------------------------------------------- operations
    def derivative(self, order: int = 1) -> PiecewisePolynomial:
        """The ``order``-th time derivative as a piecewise polynomial of degree ``D - order``."""
        _check_order(order)
        if order == 0:
            return self
        if order > self.degree:
            return PiecewisePolynomial(self.durations, np.zeros((self.pieces, 1, self.dim)))
        f = falling_factorials(self.degree, order)[order:, None]
        return PiecewisePolynomial(self.durations, self.coefficients[:, order:, :] * f)

    def tau_coefficients(self) -> np.ndarray:
        """(M, D+1, dim) coefficients in normalized local time ``tau = (t - t_i) / T_i``."""
        return time_to_tau(self.coefficients, self.durations)

    def with_degree(self, degree: int) -> PiecewisePolynomial:
        """The same trajectory stored with degree ``degree`` (zero-padded).

        Raises
        ------
        InvalidProblem
            If ``degree`` is below :attr:`degree` and the dropped coefficients are not all zero.
        """
        if degree == self.degree:
            return self
        if degree > self.degree:
            pad = np.zeros((self.pieces, degree - self.degree, self.dim))
            return PiecewisePolynomial(self.durations, np.concatenate([self.coefficients, pad], axis=1))
        if np.any(self.coefficients[:, degree + 1:, :] != 0):
            raise InvalidProblem(f"cannot lower degree {self.degree} to {degree}: higher coefficients are not zero")
        return PiecewisePolynomial(self.durations, self.coefficients[:, : degree + 1, :])

    def time_scaled(self, alpha: float) -> PiecewisePolynomial:
        """The same path traversed ``alpha`` times slower: :math:`\\sigma_\\alpha(t) = \\sigma(t/\\alpha)`.

        Durations become :math:`\\alpha T_i` and coefficients :math:`a_{ik} / \\alpha^k`, so
        the r-th derivative scales by :math:`\\alpha^{-r}` and the integral of the
        squared q-th derivative by :math:`\\alpha^{1-2q}`.
        """
        if not (np.isfinite(alpha) and alpha > 0):
            raise InvalidProblem(f"time scale must be positive and finite, got {alpha}")
        k = np.arange(self.degree + 1)
        return PiecewisePolynomial(self.durations * alpha, self.coefficients / float(alpha) ** k[None, :, None])

    def restricted(self, t_start: float, t_end: float) -> PiecewisePolynomial:
        """The part on ``[t_start, t_end]``, re-based to start at time 0.

        A piece cut at its start is re-expanded about the cut (Taylor shift,
        :math:`a'_j = \\sum_{k \\ge j} \\binom{k}{j} a_k s^{k-j}`); a piece cut at its end
        only gets a shorter duration.
        """
        if not (0.0 <= t_start < t_end <= self.duration + 1e-12):
            raise InvalidProblem(f"need 0 <= t_start < t_end <= {self.duration}, got [{t_start}, {t_end}]")
        t_end = min(t_end, self.duration)
        kn = self._knots
        first = int(np.clip(np.searchsorted(kn, t_start, side="right") - 1, 0, self.pieces - 1))
        last = int(np.clip(np.searchsorted(kn, t_end, side="left") - 1, first, self.pieces - 1))
        a = self.coefficients[first : last + 1].copy()
        starts = kn[first : last + 1].copy()
        ends = kn[first + 1 : last + 2].copy()
        shift = t_start - starts[0]
        if shift > 0:
            D = self.degree
            k = np.arange(D + 1)
            B = comb(k[None, :], k[:, None]) * shift ** np.clip(k[None, :] - k[:, None], 0, None)  # B[j,k]
            B = np.triu(B)
            a[0] = B @ a[0]
            starts[0] = t_start
        ends[-1] = t_end
        T = ends - starts
        keep = T > 1e-12 * max(1.0, self.duration)
        return PiecewisePolynomial(T[keep], a[keep])


def _check_order(order: object) -> None:
    """A derivative's order: an integer >= 0 (a bool is not one)."""
    if isinstance(order, bool) or not isinstance(order, (int, np.integer)) or order < 0:
        raise InvalidProblem(f"derivative order must be an integer >= 0, got {order!r}")


def concatenate(trajectories: Sequence[PiecewisePolynomial]) -> PiecewisePolynomial:
    """Join trajectories end to start (the second starts when the first ends).

    Degrees are zero-padded to the largest; continuity at the seams is the caller's
    business (check it with :func:`seam_jumps`).

    Raises
    ------
    InvalidProblem
        If the list is empty or dimensions differ.
    """
    trajectories = list(trajectories)
    if not trajectories:
        raise InvalidProblem("nothing to concatenate")
    dims = {t.dim for t in trajectories}
    if len(dims) != 1:
        raise InvalidProblem(f"cannot concatenate trajectories of dimensions {sorted(dims)}")
    D = max(t.degree for t in trajectories)
    padded = [t.with_degree(D) for t in trajectories]
    return PiecewisePolynomial(
        np.concatenate([t.durations for t in padded]), np.concatenate([t.coefficients for t in padded], axis=0)
    )


def seam_jumps(trajectory: PiecewisePolynomial, max_order: int) -> np.ndarray:
    """Jumps of derivatives 0..``max_order`` at the interior knots.

    Returns
    -------
    numpy.ndarray
        (M-1, max_order+1, dim): value at the start of piece i+1 minus value at the end
        of piece i, for each derivative order.
    """
    M, D = trajectory.pieces, trajectory.degree
    a = trajectory.coefficients
    T = trajectory.durations
    out = np.zeros((max(M - 1, 0), max_order + 1, trajectory.dim))
    if M < 2:
        return out
    k = np.arange(D + 1)
    for r in range(max_order + 1):
        f = falling_factorials(D, r)
        pw = np.clip(k - r, 0, None)
        end = np.einsum("k,ikd->id", f, a[:-1] * (T[:-1, None, None] ** pw[None, :, None]))
        start = f[r] * a[1:, r, :] if r <= D else np.zeros_like(end)
        out[:, r, :] = start - end
    return out


def piece_costs(c_tau: np.ndarray, durations: np.ndarray, order: int) -> np.ndarray:
    """(M,) exact :math:`\\int \\|\\sigma^{(q)}(t)\\|^2 dt` of each piece, ``q = order``.

    From the tau-coefficients ``c_tau`` (M, D+1, dim) of pieces of ``durations`` (M,):
    :math:`T_i^{1-2q} \\sum_d c_{id}^\\top H c_{id}` with :func:`cost_hessian`, in
    normalized time, which stays accurate for short and long pieces alike. The one numeric
    definition of the cost integral (its derivatives: :func:`piece_cost_gradients`); the
    QPs write the same form symbolically, in their own variables, from
    :func:`cost_hessian` (:mod:`mrfswarm.trajectory.formulation`,
    :mod:`mrfswarm.continuous.formulation`), and their tests check them against this one.
    """
    H = cost_hessian(c_tau.shape[1] - 1, order)
    return np.einsum("ikd,kl,ild->i", c_tau, H, c_tau) * np.asarray(durations, dtype=float) ** (1 - 2 * order)


def piece_cost_gradients(c_tau: np.ndarray, durations: np.ndarray, order: int) -> tuple[np.ndarray, np.ndarray]:
    """The partial derivatives of :func:`piece_costs`: (M, D+1, dim) by ``c_tau`` and (M,) by ``durations``.

    With :math:`J_i = T_i^{1-2q} \\sum_d c_{id}^\\top H c_{id}`:
    :math:`\\partial J_i / \\partial c_{id} = 2 T_i^{1-2q} H c_{id}` and, at fixed
    tau-coefficients, :math:`\\partial J_i / \\partial T_i = (1-2q) J_i / T_i`.
    """
    T = np.asarray(durations, dtype=float)
    Hc = np.einsum("kl,ild->ikd", cost_hessian(c_tau.shape[1] - 1, order), c_tau)
    by_c = 2.0 * (T ** (1 - 2 * order))[:, None, None] * Hc
    return by_c, (1 - 2 * order) * piece_costs(c_tau, T, order) / T


def integral_squared_derivative(trajectory: PiecewisePolynomial, order: int) -> float:
    """Exact :math:`\\int_0^{T} \\|\\sigma^{(q)}(t)\\|^2 dt` with ``q = order`` (see :func:`piece_costs`)."""
    return float(piece_costs(trajectory.tau_coefficients(), trajectory.durations, order).sum())
