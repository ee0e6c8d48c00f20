"""Every piece of many trajectories in one array, for the checks over a whole swarm.

The final checks of a plan (exact maxima of speed, acceleration and jerk, the exact
minimum separation, the certificate) apply the same small linear maps (monomial to
Bernstein control points, values at fixed :math:`\\tau`) to every piece of every robot.
Done one trajectory at a time, or with ``np.einsum`` over (..., K, dim) arrays, this took
seconds for a thousand robots and 300 steps. Here the pieces are stacked once with the
coefficient axis first, (K, P, dim), so that a map is one product of a small matrix with
a wide one, ``(R, K) @ (K, P dim)``, fast in BLAS whatever its number of threads (the
tall product ``(P dim, K) @ (K, R)`` was 5-10 times slower with OpenBLAS's threads on a
busy machine). Products are taken over :data:`PIECE_CHUNK` pieces at a time: small
products pay the threads' start each time (on a loaded machine, 38 products of 8000
pieces took 0.4-0.8 s, one of 300 000 pieces 0.03 s), and the chunk bounds the memory.
A matrix product sums in another order than ``einsum``, so its results may differ from
it in the last bits.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from mrfswarm.trajectory.polynomial import PiecewisePolynomial, falling_factorials

#: Pieces mapped by one matrix product (some 20 MB for a few maps of degree-7 pieces in 2-D).
PIECE_CHUNK = 1 << 16


def stacked_tau_coefficients(trajectories: Sequence[PiecewisePolynomial], order: int = 0) -> np.ndarray:
    """Tau-coefficients of the ``order``-th derivative of every piece, trajectory after trajectory.

    Parameters
    ----------
    trajectories
        Trajectories of one degree ``D`` and dimension (any numbers of pieces).
    order
        Derivative order r >= 0.

    Returns
    -------
    numpy.ndarray
        (D + 1 - r, P, dim) (a single zero coefficient when r > D), P the total number of
        pieces: the numbers of ``tr.derivative(order).tau_coefficients()``, concatenated,
        bit for bit (the same operations on the same numbers), coefficient axis first.
    """
    a = np.concatenate([tr.coefficients for tr in trajectories])  # (P, D+1, dim)
    D = a.shape[1] - 1
    if order > D:
        return np.zeros((1, len(a), a.shape[2]))
    if order:
        a = a[:, order:, :] * falling_factorials(D, order)[order:, None]
    k = np.arange(a.shape[1])
    T0 = trajectories[0].durations
    if all(np.array_equal(tr.durations, T0) for tr in trajectories):  # one time grid: its powers once
        N, M = len(trajectories), len(T0)
        powers = T0[None, :] ** k[:, None]  # (K, M)
        out = np.multiply(a.reshape(N, M, len(k), -1).transpose(2, 0, 1, 3), powers[:, None, :, None], order="C")
        return out.reshape(len(k), N * M, -1)
    T = np.concatenate([tr.durations for tr in trajectories])
    return np.multiply(a.transpose(1, 0, 2), T[None, :, None] ** k[:, None, None], order="C")


def map_coefficients(matrix: np.ndarray, coefficients: np.ndarray) -> np.ndarray:
    """``matrix`` (R, K) applied to the first axis of ``coefficients`` (K, ...), as one matrix product: (R, ...)."""
    K = coefficients.shape[0]
    return (matrix @ coefficients.reshape(K, -1)).reshape((matrix.shape[0],) + coefficients.shape[1:])


def map_coefficients_in_order(matrix: np.ndarray, coefficients: np.ndarray) -> np.ndarray:
    """:func:`map_coefficients` summed term by term in the order of the coefficients, over whole arrays.

    The sums ``np.einsum`` forms, so the numbers of
    :func:`~mrfswarm.trajectory.bernstein.tau_control_points` bit for bit (the tests hold
    it to that); 3-6 times slower than the matrix product, 2-3 times faster than
    ``einsum`` over (..., K, dim) arrays. For what a result reports, where a last bit can
    decide (a pair exactly at the safety distance is near or not).
    """
    out = matrix[:, 0].reshape((-1,) + (1,) * (coefficients.ndim - 1)) * coefficients[0]
    for k in range(1, coefficients.shape[0]):
        out += matrix[:, k].reshape((-1,) + (1,) * (coefficients.ndim - 1)) * coefficients[k]
    return out


def norms(points: np.ndarray) -> np.ndarray:
    """Euclidean norms of points (..., dim): (...).

    By ``np.hypot`` one coordinate at a time: for planar points exactly ``np.hypot(x, y)``,
    in space ``hypot(hypot(x, y), z)`` (as accurate, and no overflow).
    """
    out = np.hypot(points[..., 0], points[..., 1]) if points.shape[-1] > 1 else np.abs(points[..., 0])
    for d in range(2, points.shape[-1]):
        out = np.hypot(out, points[..., d])
    return out


def squared_norms(points: np.ndarray) -> np.ndarray:
    """Squared norms of points (..., dim): (...).

    Summed one coordinate at a time over whole arrays (``np.add.reduce`` over a last axis
    of length 2 loops per point, 20 times slower); for planar points the same sum as
    ``np.linalg.norm``'s.
    """
    out = points[..., 0] * points[..., 0]
    for d in range(1, points.shape[-1]):
        out += points[..., d] * points[..., d]
    return out
