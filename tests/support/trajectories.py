"""References for the trajectory tests: random waypoints, a sparse KKT solve and an exact rational solve.

``tests/trajectory/test_support.py`` checks the references themselves.
"""

from fractions import Fraction

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from mrfswarm.trajectory import MinSnapProblem, PiecewisePolynomial, min_snap_qp
from mrfswarm.trajectory.banded import _pattern
from mrfswarm.trajectory.polynomial import tau_to_time


def random_walk(rng, pieces, dim=2, step=(0.5, 1.5)):
    """Waypoints of a planar/3-D random walk with step lengths in ``step``."""
    d = rng.normal(size=(pieces, dim))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    d *= rng.uniform(*step, size=(pieces, 1))
    return np.vstack([np.zeros(dim), np.cumsum(d, axis=0)])


def kkt_trajectory(problem: MinSnapProblem) -> PiecewisePolynomial:
    """Solve the formulated equality-only QP through its KKT system with scipy (reference only)."""
    qp, norm = min_snap_qp(problem)
    assert not qp.has_inequalities
    K = sp.bmat([[qp.P, qp.A.T], [qp.A, None]], format="csc")
    z = spla.spsolve(K, np.concatenate([np.zeros(qp.n), qp.l]))
    c = norm.tau_coefficients(problem, z[: qp.n])
    return PiecewisePolynomial(problem.durations, tau_to_time(c, problem.durations))


def exact_banded_coefficients(problem: MinSnapProblem) -> np.ndarray:
    """The banded system solved exactly in rational arithmetic (tau-coefficients, rounded once)."""
    s = problem.shape
    q = problem.derivative
    pat = _pattern(s.pieces, q, s.start_order, s.end_order)
    T = [Fraction(float(t)) for t in problem.durations]
    ratio = [T[i] / T[i + 1] for i in range(len(T) - 1)] + [Fraction(1)]
    n = pat.n
    A = [[Fraction(0)] * n for _ in range(n)]
    for r, c, k, e, kn in zip(pat.row, pat.col, pat.const, pat.expo, pat.knot):
        A[r][c] += Fraction(float(k)) * ratio[kn] ** int(e)
    out = np.zeros((n, s.dim))
    for d in range(s.dim):
        b = [Fraction(0)] * n
        for r, w in zip(pat.wp_rows, pat.wp_index):
            b[r] = Fraction(float(problem.waypoints[w, d]))
        for j, r in enumerate(pat.g0_rows):
            b[r] = Fraction(float(problem.start[j, d])) * T[0] ** (j + 1)
        for j, r in enumerate(pat.g1_rows):
            b[r] = Fraction(float(problem.end[j, d])) * T[-1] ** (j + 1)
        M = [row[:] + [b[i]] for i, row in enumerate(A)]
        for col in range(n):  # Gauss-Jordan, exact
            piv = next(i for i in range(col, n) if M[i][col] != 0)
            M[col], M[piv] = M[piv], M[col]
            inv = 1 / M[col][col]
            M[col] = [v * inv for v in M[col]]
            for i in range(n):
                if i != col and M[i][col] != 0:
                    f = M[i][col]
                    M[i] = [a - f * bb for a, bb in zip(M[i], M[col])]
        out[:, d] = [float(M[i][n]) for i in range(n)]
    return out.reshape(s.pieces, 2 * q, s.dim)
