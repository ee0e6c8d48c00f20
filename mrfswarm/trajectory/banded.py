"""Closed-form min-snap without inequalities: one banded linear solve, linear in the pieces.

For degree :math:`D = 2q - 1` the optimality conditions of the equality-constrained
problem (:mod:`mrfswarm.trajectory.problem`) form a square, banded linear system in the
coefficients — the idea of MINCO (Wang, Xu, Gao et al., "Geometrically Constrained
Trajectory Optimization for Multicopters", IEEE T-RO 38(5), 2022). Integrating
:math:`\\delta J = 2\\int \\sigma^{(q)} \\delta\\sigma^{(q)}` by parts on each piece gives

.. math::

    \\delta J = 2 \\sum_i \\Big[ \\sum_{j=0}^{q-1} (-1)^j \\sigma^{(q+j)} \\delta\\sigma^{(q-1-j)} \\Big]_{t_i}^{t_{i+1}}
                + 2 \\sum_i \\int (-1)^q \\sigma^{(2q)} \\delta\\sigma,

so the optimum has :math:`\\sigma^{(2q)} = 0` inside pieces (degree 2q-1 suffices) and,
where :math:`\\delta\\sigma^{(r)}` is free, :math:`\\sigma^{(2q-1-r)} = 0` (a free end),
where it is shared by two pieces, :math:`\\sigma^{(2q-1-r)}` continuous. Per interior
knot (continuity order :math:`c \\ge q - 1`, which the problem requires): both pieces
reach the waypoint (2 rows) and derivatives :math:`1, \\dots, 2q-2` are continuous
(:math:`2q-2` rows; those above :math:`c` are the natural conditions, so every
:math:`c` in :math:`q-1..2q-2` has the same optimum);
and per end, with derivatives :math:`1..k` given: position, those :math:`k` values, and
:math:`\\sigma^{(2q-1-r)} = 0` for :math:`r = k+1..q-1` (``q`` rows). That is
:math:`2qM` equations for :math:`2qM` coefficients per dimension. The unknowns are
tau-coefficients ordered piece by piece and each row is scaled by its piece's
:math:`T^r`, so every entry is :math:`\\pm k!/(k-r)!` times a ratio
:math:`(T_i/T_{i+1})^{\\pm r}`; with rows ordered as above (left-only, coupling, right-only) the lower and upper
bandwidths are both :math:`q`.
The matrix is assembled from precomputed indices in one vectorized step and factorized
by LAPACK ``dgbtrf`` (banded LU with partial pivoting): :math:`O(M q^3)`.

The duration gradient follows by the adjoint method. With :math:`A(T) c = b(T)` and
:math:`J(c, T) = \\sum_i T_i^{1-2q} c_i^\\top H c_i`,

.. math::

    \\frac{dJ^*}{dT_j} = \\frac{\\partial J}{\\partial T_j}
        - \\lambda^\\top\\Big(\\frac{\\partial A}{\\partial T_j} c - \\frac{\\partial b}{\\partial T_j}\\Big),
    \\qquad A^\\top \\lambda = \\frac{\\partial J}{\\partial c},

one more banded solve with the same factors (``dgbtrs``, transposed).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.linalg import lapack

from mrfswarm.trajectory.polynomial import falling_factorials, piece_cost_gradients, piece_costs
from mrfswarm.trajectory.problem import MinSnapProblem
from solvers.errors import InvalidProblem, SolverError


@dataclass(frozen=True)
class _Pattern:
    """Where every nonzero of the banded system goes, for one problem shape."""

    n: int
    kl: int
    ku: int
    flat: np.ndarray  # index into the (n, 2kl+ku+1) C array whose transpose is LAPACK's band storage
    const: np.ndarray  # entry = const * ratio[knot] ** expo
    expo: np.ndarray
    knot: np.ndarray
    row: np.ndarray
    col: np.ndarray
    wp_rows: np.ndarray  # rows whose right-hand side is a waypoint ...
    wp_index: np.ndarray  # ... this one
    g0_rows: np.ndarray  # rows of the given start derivatives 1..ks
    g1_rows: np.ndarray  # rows of the given end derivatives 1..ke


def _row_terms(q: int, ks: int, ke: int):
    """Row templates: lists of terms ``(side, tau, order, sign)``; side 0 = left piece.

    Returns the start rows, one interior knot's rows and the end rows, each a list of
    ``(terms, rhs)`` with rhs ``("w", offset)`` (waypoint), ``("g0", r)``, ``("g1", r)``
    or ``None`` (zero).
    """
    Row = tuple[list[tuple[int, float, int, float]], tuple[str, int] | None]
    start: list[Row] = [([(0, 0.0, 0, 1.0)], ("w", 0))]
    start += [([(0, 0.0, r, 1.0)], ("g0", r)) for r in range(1, ks + 1)]
    start += [([(0, 0.0, 2 * q - 1 - r, 1.0)], None) for r in range(ks + 1, q)]
    end: list[Row] = [([(0, 1.0, 0, 1.0)], ("w", 1))]
    end += [([(0, 1.0, r, 1.0)], ("g1", r)) for r in range(1, ke + 1)]
    end += [([(0, 1.0, 2 * q - 1 - r, 1.0)], None) for r in range(ke + 1, q)]
    cont = range(1, 2 * q - 1)  # c >= q - 1: the optimum is C^(2q-2) whatever c is
    # left-only row, rows coupling both pieces, right-only row (keeps the band tight)
    knot: list[Row] = [([(0, 1.0, 0, 1.0)], ("w", 1))]
    knot += [([(0, 1.0, m, 1.0), (1, 0.0, m, -1.0)], None) for m in cont]
    knot += [([(1, 0.0, 0, 1.0)], ("w", 1))]
    assert len(start) == q and len(end) == q and len(knot) == 2 * q
    return start, knot, end


@lru_cache(maxsize=64)
def _pattern(M: int, q: int, ks: int, ke: int) -> _Pattern:
    N = 2 * q
    D = N - 1
    n = N * M
    start, knot, end = _row_terms(q, ks, ke)

    def expand(rows, row0, piece0):
        """Entries of template rows placed at row ``row0`` on pieces ``piece0 + side``."""
        e_row, e_side, e_k, e_const, e_expo = [], [], [], [], []
        rhs = []
        for j, (terms, r_rhs) in enumerate(rows):
            row_side = terms[0][0]
            for side, tau, m, sign in terms:
                f = falling_factorials(D, m)
                for k in range(m, D + 1):
                    v = sign * f[k] * tau ** (k - m)
                    if v == 0.0:
                        continue
                    e_row.append(j)
                    e_side.append(side)
                    e_k.append(k)
                    e_const.append(v)
                    # row scaled by T_rowpiece^m: the entry carries (T_row / T_term)^m = ratio^(+-m)
                    e_expo.append(0 if side == row_side else (m if row_side == 0 else -m))
            rhs.append((j, r_rhs))
        return (np.array(e_row) + row0, np.array(e_side), np.array(e_k), np.array(e_const), np.array(e_expo)), rhs

    rows, cols, consts, expos, knots = [], [], [], [], []
    wp_rows, wp_index, g0_rows, g1_rows = [], [], [], []

    def add(template, row0, piece0, knot_ids):
        (r, side, k, const, expo), rhs = template
        R = r[None, :] + row0[:, None]
        C = (piece0[:, None] + side[None, :]) * N + k[None, :]
        rows.append(R.ravel())
        cols.append(C.ravel())
        consts.append(np.broadcast_to(const, R.shape).ravel())
        expos.append(np.broadcast_to(expo, R.shape).ravel())
        knots.append(np.broadcast_to(knot_ids[:, None], R.shape).ravel())
        return rhs

    zero = np.zeros(1, dtype=int)
    rhs = add(expand(start, 0, 0), zero, zero, np.full(1, max(M - 1, 0)))
    for j, spec in rhs:
        if spec is None:
            continue
        if spec[0] == "w":
            wp_rows.append(j)
            wp_index.append(0)
        else:
            g0_rows.append(j)
    if M > 1:
        i = np.arange(M - 1)
        rhs = add(expand(knot, 0, 0), q + N * i, i, i)
        for j, spec in rhs:
            if spec is not None:  # waypoint i+1 on both sides
                wp_rows.extend(q + N * i + j)
                wp_index.extend(i + 1)
    last = np.array([M - 1])
    rhs = add(expand(end, 0, 0), q + N * (M - 1) + zero, last, np.full(1, max(M - 1, 0)))
    for j, spec in rhs:
        if spec is None:
            continue
        if spec[0] == "w":
            wp_rows.append(q + N * (M - 1) + j)
            wp_index.append(M)
        else:
            g1_rows.append(q + N * (M - 1) + j)

    row = np.concatenate(rows)
    col = np.concatenate(cols)
    kl, ku = int(np.max(row - col)), int(np.max(col - row))  # q and q with this row order
    nband = 2 * kl + ku + 1
    band_row = kl + ku + row - col
    arrays = dict(
        flat=col * nband + band_row, const=np.concatenate(consts), expo=np.concatenate(expos),
        knot=np.concatenate(knots), row=row, col=col, wp_rows=np.array(wp_rows, dtype=int),
        wp_index=np.array(wp_index, dtype=int), g0_rows=np.array(g0_rows, dtype=int), g1_rows=np.array(g1_rows, dtype=int),
    )
    for a in arrays.values():
        a.setflags(write=False)
    return _Pattern(n=n, kl=kl, ku=ku, **arrays)


@dataclass(frozen=True)
class BandedSolution:
    """Result of the banded closed form.

    Attributes
    ----------
    coefficients
        (M, 2q, dim) tau-coefficients.
    cost
        :math:`J^* = \\int \\|\\sigma^{(q)}\\|^2 dt`.
    gradient
        (M,) :math:`dJ^*/dT`, when asked for, else ``None``.
    """

    coefficients: np.ndarray
    cost: float
    gradient: np.ndarray | None = None


def supports(problem: MinSnapProblem) -> bool:
    """True when the banded closed form applies: degree 2q-1, no corridor, exact waypoints."""
    return (problem.degree == 2 * problem.derivative - 1 and not problem.has_corridor
            and problem.waypoint_tolerance is None)


def solve_banded(problem: MinSnapProblem, gradient: bool = False) -> BandedSolution:
    """Solve ``problem`` (degree ``2q - 1``, no corridor) in closed form.

    Parameters
    ----------
    problem
        The problem; its continuity order is capped at ``2q - 2`` by its validation.
    gradient
        Also return :math:`dJ^*/dT` (adjoint solve, exact).

    Raises
    ------
    InvalidProblem
        If the degree is not ``2q - 1`` or the problem has a corridor.
    SolverError
        If the system is singular (LAPACK ``info > 0``).
    """
    if not supports(problem):
        raise InvalidProblem(
            "the banded closed form needs degree 2q - 1 and no corridor; "
            f"got degree {problem.degree}, q = {problem.derivative}, corridor={'yes' if problem.has_corridor else 'no'}"
        )
    q = problem.derivative
    s = problem.shape
    M = s.pieces
    pat = _pattern(M, q, s.start_order, s.end_order)
    T = problem.durations
    ratio = np.append(T[:-1] / T[1:], 1.0)
    vals = pat.const * ratio[pat.knot] ** pat.expo
    nband = 2 * pat.kl + pat.ku + 1
    abT = np.zeros((pat.n, nband))
    abT.ravel()[pat.flat] = vals
    lu, piv, info = lapack.dgbtrf(abT.T, pat.kl, pat.ku, overwrite_ab=1)
    if info != 0:
        raise SolverError(f"closed_form: singular min-snap system (LAPACK dgbtrf info={info})", backend="closed_form",
                          status=f"info={info}")
    B = np.zeros((pat.n, s.dim))
    B[pat.wp_rows] = problem.waypoints[pat.wp_index]
    m0 = np.arange(1, s.start_order + 1)
    m1 = np.arange(1, s.end_order + 1)
    if s.start_order:
        B[pat.g0_rows] = problem.start * (T[0] ** m0)[:, None]
    if s.end_order:
        B[pat.g1_rows] = problem.end * (T[-1] ** m1)[:, None]
    X, info = lapack.dgbtrs(lu, pat.kl, pat.ku, B, piv)
    if info != 0:
        raise SolverError(f"closed_form: dgbtrs failed (info={info})", backend="closed_form", status=f"info={info}")
    N = 2 * q
    coeffs = X.reshape(M, N, s.dim)
    costs = piece_costs(coeffs, T, q)
    cost = float(costs.sum())
    if not np.isfinite(cost):
        raise SolverError("closed_form: non-finite solution", backend="closed_form", status="nonfinite")
    grad = None
    if gradient:
        # adjoint: A^T lam = dJ/dc; the cost's own dependence on T at fixed c, then the system's
        dJdc, grad = piece_cost_gradients(coeffs, T, q)
        lam, info = lapack.dgbtrs(lu, pat.kl, pat.ku, dJdc.reshape(pat.n, s.dim), piv, trans=1)
        # d(entry)/dT: entry = const * (T_i / T_{i+1})^expo on knot i
        contrib = vals * pat.expo * np.einsum("ed,ed->e", lam[pat.row], X[pat.col])
        mask = pat.expo != 0
        kn = pat.knot[mask]
        cm = contrib[mask]
        grad -= np.bincount(kn, weights=cm / T[kn], minlength=M)
        grad += np.bincount(kn + 1, weights=cm / T[kn + 1], minlength=M + 1)[:M]
        # d(rhs)/dT: given derivatives g_r T^r
        if s.start_order:
            grad[0] += np.sum(lam[pat.g0_rows] * B[pat.g0_rows] * (m0 / T[0])[:, None])
        if s.end_order:
            grad[-1] += np.sum(lam[pat.g1_rows] * B[pat.g1_rows] * (m1 / T[-1])[:, None])
    return BandedSolution(coefficients=coeffs, cost=cost, gradient=grad)
