"""Bernstein (Bezier) control points of polynomial pieces and of their derivatives.

A piece of degree ``D`` in normalized time :math:`\\tau \\in [0, 1]` with monomial
coefficients :math:`c_k` is, in the Bernstein basis,

.. math::

    p(\\tau) = \\sum_{m=0}^{D} P_m \\binom{D}{m} \\tau^m (1-\\tau)^{D-m}, \\qquad
    P_m = \\sum_{k=0}^{m} \\frac{\\binom{m}{k}}{\\binom{D}{k}} c_k .

The basis functions are non-negative and sum to one, so :math:`p(\\tau)` lies in the
convex hull of its control points :math:`P_m` for every :math:`\\tau` (Farouki, "The
Bernstein polynomial basis: a centennial retrospective", CAGD 29, 2012). The r-th
:math:`\\tau`-derivative is again a Bernstein polynomial, of degree :math:`D - r`, with
control points :math:`\\frac{D!}{(D-r)!} \\Delta^r P` (forward differences); dividing by
:math:`T^r` gives the control points of the r-th time derivative of a piece of duration
:math:`T`. This is what turns "inside a convex region" and "below a speed limit" into
finitely many linear conditions that hold for all t.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from scipy.special import comb

from mrfswarm.trajectory.polynomial import PiecewisePolynomial, falling_factorials


@lru_cache(maxsize=32)
def monomial_to_bernstein(degree: int) -> np.ndarray:
    """(D+1, D+1) matrix ``B`` with ``P = B @ c`` (control points from tau-coefficients). Read-only."""
    m = np.arange(degree + 1)
    B = np.where(m[None, :] <= m[:, None], comb(m[:, None], m[None, :]) / comb(degree, m[None, :]), 0.0)
    B.setflags(write=False)
    return B


@lru_cache(maxsize=64)
def difference_matrix(degree: int, order: int) -> np.ndarray:
    """(D+1-r, D+1) matrix of :math:`\\frac{D!}{(D-r)!}\\Delta^r`: control points of the r-th tau-derivative.

    Read-only.
    """
    Dm = np.eye(degree + 1)
    for _ in range(order):
        Dm = Dm[1:] - Dm[:-1]
    Dm = Dm * falling_factorials(degree, order)[-1]
    Dm.setflags(write=False)
    return Dm


@lru_cache(maxsize=64)
def subdivision_matrix(degree: int, parts: int) -> np.ndarray:
    """(parts (n+1), n+1) matrix: Bernstein control points on [0, 1] -> those of the ``parts`` equal sub-intervals.

    A polynomial restricted to [k/S, (k+1)/S] is again a polynomial of the same degree in
    its own local parameter; the convex hulls of the pieces' control points enclose the
    curve more tightly than the whole one's (the control points converge to the curve
    quadratically in 1/S). Read-only.
    """
    n = degree
    B = monomial_to_bernstein(n)
    Binv = np.linalg.inv(B)
    blocks = []
    for k in range(parts):
        # monomial coefficients of c(tau) -> those of c((k + u) / S) in u
        R = np.zeros((n + 1, n + 1))
        for j in range(n + 1):
            col = np.polynomial.polynomial.polypow([k / parts, 1.0 / parts], j)
            R[: len(col), j] = col
        blocks.append(B @ R @ Binv)
    out = np.vstack(blocks)
    out.setflags(write=False)
    return out


@lru_cache(maxsize=64)
def control_point_matrix(degree: int, order: int = 0, parts: int = 1) -> np.ndarray:
    """(parts (D+1-r), D+1) matrix from tau-coefficients to the control points of :func:`tau_control_points`.

    Read-only.
    """
    M = difference_matrix(degree, order) @ monomial_to_bernstein(degree)
    if parts > 1:
        M = subdivision_matrix(degree - order, parts) @ M
    M.setflags(write=False)
    return M


def tau_control_points(tau_coefficients: np.ndarray, order: int = 0, parts: int = 1) -> np.ndarray:
    """Control points of the ``order``-th tau-derivative of pieces given by tau-coefficients.

    Parameters
    ----------
    tau_coefficients
        (..., D+1, dim) coefficients in increasing power of tau.
    order
        Derivative order r >= 0.
    parts
        Split each piece into this many equal sub-intervals and return all their control
        points (a tighter hull; see :func:`subdivision_matrix`).

    Returns
    -------
    numpy.ndarray
        (..., parts (D+1-r), dim).
    """
    M = control_point_matrix(tau_coefficients.shape[-2] - 1, order, parts)
    return np.einsum("mk,...kd->...md", M, tau_coefficients)


def control_points(trajectory: PiecewisePolynomial, order: int = 0, parts: int = 1) -> np.ndarray:
    """Control points of the ``order``-th time derivative of every piece of ``trajectory``.

    Returns
    -------
    numpy.ndarray
        (M, parts (D+1-r), dim): piece i's r-th derivative lies in the convex hull of row
        i for all t in the piece (of each sub-interval's points in its sub-interval).
    """
    T = trajectory.durations
    return tau_control_points(trajectory.tau_coefficients(), order, parts) / T[:, None, None] ** order
