"""The min-snap QP, formulated once with CasADi symbols and compiled once per shape.

Each piece is a polynomial in its normalized local time :math:`\\tau = (t - t_i)/T_i`,
written in a Hermite basis: the derivatives :math:`0..q-1` at its two knots plus, when
the degree :math:`D > 2q-1`, "bubble" terms that vanish to order :math:`q` at both ends,

.. math::

    c_i = \\mathcal H \\,\\mathrm{diag}(\\tilde T_i^{r})_{r} \\begin{bmatrix} y_i \\\\ y_{i+1} \\end{bmatrix}
          + \\mathcal B\\, b_i, \\qquad
    \\mathcal B_m(\\tau) = (4\\tau(1-\\tau))^q \\tau^m,\\ m = 0..D-2q,

where :math:`c_i` are the piece's tau-coefficients, :math:`y_j = (\\sigma(t_j),
\\dots, \\sigma^{(q-1)}(t_j))` scaled to normalized time (:math:`\\tilde y_{j,r} =
\\sigma^{(r)}(t_j)\\, T_s^r / L`) and :math:`\\mathcal H` maps the tau-derivatives at
:math:`\\tau = 0, 1` to the coefficients of the degree-:math:`2q-1` Hermite
interpolant. The knot derivatives are shared by the two pieces at a knot, so
continuity up to :math:`q - 1` holds by construction, and the variables are physical
quantities of comparable size whatever the durations: the QP stays well conditioned for
first-order solvers (the per-piece monomial form made OSQP stall at duration ratios of
10 because its cost weights go as :math:`T_i^{1-2q}`).

With :math:`H` from :func:`~mrfswarm.trajectory.polynomial.cost_hessian` and
:math:`F_r(\\tau)` the r-th derivative row, the QP is

.. math::

    \\min \\sum_{d,i} \\tilde T_i^{1-2q} c_i^{(d)\\top} H c_i^{(d)}
    \\quad \\text{s.t.} \\quad
    \\begin{aligned}
    & \\tilde y_{j,0} = \\tilde w_j, \\quad \\tilde y_{0,r} = \\tilde g^{0}_r,
      \\quad \\tilde y_{M,r} = \\tilde g^{1}_r \\quad (\\text{given end derivatives}), \\\\
    & \\rho_i^{r/2} F_r(1) c_i - \\rho_i^{-r/2} F_r(0) c_{i+1} = 0,
      \\ \\rho_i = \\tilde T_{i+1}/\\tilde T_i, \\ r = q..c \\quad (\\text{continuity above } q-1), \\\\
    & \\tilde l_{is} \\le F_0(\\tau_s) c_i \\le \\tilde u_{is} \\quad (\\text{corridor samples}),
    \\end{aligned}

exactly :math:`\\int \\|\\sigma^{(q)}\\|^2 dt` in normalized units since
:math:`\\sigma^{(r)}(t) = T_i^{-r} d^r/d\\tau^r`. Writing a piece's local variables
:math:`z_i = (y_i, y_{i+1}, b_i)`, :math:`c_i = E\\,\\mathrm{diag}(\\tilde T_i^{r_a}) z_i` with the
constant basis :math:`E = [\\mathcal H, \\mathcal B]` (:math:`r_a` the derivative order of
variable :math:`a`, 0 for bubbles), so the piece's cost block is
:math:`2 G_{ab} \\tilde T_i^{1-2q+r_a+r_b}` with :math:`G = E^\\top H E` computed once: ``P`` is
written out symbolically in that form (no automatic differentiation, about 200 SX
instructions per piece), ``A`` is the Jacobian of the constraint expressions.
Variables are ordered dimension-major, then ``y_0, b_0, y_1, b_1, ..., y_M``. The
parameters are the (normalized) waypoints, durations, corridor bounds and end
derivatives; one :class:`casadi.Function` per
:class:`~mrfswarm.trajectory.problem.MinSnapShape` returns ``(P, A, l, u)`` (``q = 0``).
The sparsity patterns are read once at compile time, so turning an evaluation into
:class:`scipy.sparse.csc_matrix` only copies nonzeros, and the evaluation writes
straight into numpy buffers (``Function.buffer``).

The caller (:mod:`mrfswarm.trajectory.min_snap`) feeds normalized data: positions
centred and divided by their half-extent :math:`L`, durations divided by their geometric
mean :math:`T_s`. Both maps are exact (the optimum is equivariant under them).
"""

from __future__ import annotations

import logging
import threading
import time
from functools import lru_cache

import numpy as np
import scipy.sparse as sp

from mrfswarm.trajectory.corridor import corridor_sample_taus
from mrfswarm.trajectory.polynomial import cost_hessian, derivative_row
from mrfswarm.trajectory.problem import MinSnapShape
from solvers.qp import QPProblem

log = logging.getLogger(__name__)


@lru_cache(maxsize=32)
def hermite_basis(degree: int, order: int) -> tuple[np.ndarray, np.ndarray]:
    """The piece basis in tau-coefficients.

    Returns
    -------
    hermite : numpy.ndarray
        (D+1, 2q): column ``r`` (``q + r``) is the degree-``2q-1`` polynomial whose
        tau-derivatives ``0..q-1`` are ``delta_r`` at ``tau = 0`` (``tau = 1``) and zero at
        the other end.
    bubble : numpy.ndarray
        (D+1, D+1-2q): column ``m`` is :math:`(4\\tau(1-\\tau))^q \\tau^m`.
    """
    D, q = degree, order
    N = D + 1
    C = np.array([derivative_row(2 * q - 1, r, 0.0) for r in range(q)] + [derivative_row(2 * q - 1, r, 1.0) for r in range(q)])
    herm = np.zeros((N, 2 * q))
    herm[: 2 * q] = np.linalg.solve(C, np.eye(2 * q))
    nb = N - 2 * q
    bub = np.zeros((N, nb))
    base = np.polynomial.polynomial.polypow([0.0, 4.0, -4.0], q)  # (4 tau (1 - tau))^q, degree 2q
    for m in range(nb):
        bub[m : m + 2 * q + 1, m] = base
    herm.setflags(write=False)
    bub.setflags(write=False)
    return herm, bub


class CompiledMinSnap:
    """The compiled QP of one shape: evaluate it into a :class:`~solvers.qp.QPProblem`.

    One evaluation buffer per shape, guarded by a lock: instances are shared (cached per
    shape), so threads planning at once take turns evaluating.
    """

    def __init__(self, shape: MinSnapShape) -> None:
        import casadi as ca

        t0 = time.perf_counter()
        self.shape = shape
        basis = _PieceBasis(shape)
        self.n = shape.dim * basis.per_dim
        sym = _Symbols(shape, self.n)
        powers = _DurationPowers(sym.T, shape.pieces)
        P = _cost_matrix(shape, basis, powers, self.n)
        g, lb, ub = _constraints(shape, basis, sym, powers)
        g_all = ca.vertcat(*g)
        A = ca.jacobian(g_all, sym.x)
        self.m = g_all.numel()
        self._position_rows = _position_rows(shape)
        self._compile(ca.Function("min_snap_qp", [sym.W, sym.T, sym.lo, sym.hi, sym.g0, sym.g1],
                                  [P, A, ca.vertcat(*lb), ca.vertcat(*ub)]))
        # numpy side of the basis, to turn a solution into tau-coefficients
        self._E, self._offset, self._rpow = basis.E, basis.offset, basis.rpow
        self._stride, self._per_dim = basis.stride, basis.per_dim
        self.compile_time_s = time.perf_counter() - t0
        log.debug("compiled min-snap QP %s in %.3f s (n=%d, m=%d)", shape, self.compile_time_s, self.n, self.m)

    def _compile(self, fn) -> None:
        """Keep ``fn``'s output patterns and an evaluation buffer that writes into numpy arrays."""
        self._fn = fn
        sP, sA = fn.sparsity_out(0), fn.sparsity_out(1)
        self._P_pattern = (np.asarray(sP.row(), np.int32), np.asarray(sP.colind(), np.int32))
        self._A_pattern = (np.asarray(sA.row(), np.int32), np.asarray(sA.colind(), np.int32))
        self._nnz = (sP.nnz(), sA.nnz())
        self._buf, self._eval = fn.buffer()
        self._lock = threading.Lock()

    def evaluate(self, waypoints: np.ndarray, durations: np.ndarray, lower: np.ndarray | None,
                 upper: np.ndarray | None, start: np.ndarray, end: np.ndarray,
                 waypoint_tolerance: np.ndarray | None = None) -> QPProblem:
        """The standard-form QP for normalized data.

        Parameters
        ----------
        waypoints
            (M+1, dim).
        durations
            (M,).
        lower, upper
            (M, K, dim) corridor bounds, or ``None`` when ``K = 0``.
        start, end
            (k, dim) given derivatives (normalized time) at each end.
        waypoint_tolerance
            (M+1, dim) half-widths: knot j may lie within ``waypoints[j] +- tolerance[j]``
            (0: exactly on it). Only bounds change, so the shape does not.
        """
        outs = [np.empty(self._nnz[0]), np.empty(self._nnz[1]), np.empty(self.m), np.empty(self.m)]
        self.evaluate_into(outs, waypoints, durations, lower, upper, start, end, waypoint_tolerance)
        P = sp.csc_matrix((outs[0], *self._P_pattern), shape=(self.n, self.n))
        A = sp.csc_matrix((outs[1], *self._A_pattern), shape=(self.m, self.n))
        return QPProblem(P=P, q=np.zeros(self.n), A=A, l=outs[2], u=outs[3])

    def evaluate_into(self, outs: list[np.ndarray], waypoints: np.ndarray, durations: np.ndarray,
                      lower: np.ndarray | None, upper: np.ndarray | None, start: np.ndarray, end: np.ndarray,
                      waypoint_tolerance: np.ndarray | None = None) -> None:
        """Write the nonzeros of P and A, and l and u, into the contiguous arrays ``outs``.

        The arguments are those of :meth:`evaluate`; the patterns are :attr:`patterns`.
        Used to stack many problems of this shape into one block-diagonal QP.
        """
        args = [
            np.ascontiguousarray(waypoints.T, dtype=float).reshape(-1),
            np.ascontiguousarray(durations, dtype=float),
            np.empty(0) if lower is None else np.ascontiguousarray(np.moveaxis(lower, 2, 0), dtype=float).reshape(-1),
            np.empty(0) if upper is None else np.ascontiguousarray(np.moveaxis(upper, 2, 0), dtype=float).reshape(-1),
            np.ascontiguousarray(start.T, dtype=float).reshape(-1),
            np.ascontiguousarray(end.T, dtype=float).reshape(-1),
        ]
        with self._lock:
            for i, a in enumerate(args):
                self._buf.set_arg(i, memoryview(a))
            for i, o in enumerate(outs):
                self._buf.set_res(i, memoryview(o))
            self._eval()
        if waypoint_tolerance is not None:
            rows = self._position_rows.T  # (M+1, dim)
            outs[2][rows] -= waypoint_tolerance
            outs[3][rows] += waypoint_tolerance

    @property
    def patterns(self) -> tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]:
        """CSC (row indices, column pointers) of P and of A."""
        return self._P_pattern, self._A_pattern

    def coefficients(self, x: np.ndarray, durations: np.ndarray) -> np.ndarray:
        """(M, D+1, dim) tau-coefficients (normalized units) of a solution ``x``.

        ``durations`` are the normalized durations the QP was evaluated with.
        """
        s = self.shape
        M = s.pieces
        X = np.asarray(x, dtype=float).reshape(s.dim, self._per_dim)
        Z = X[:, self._offset[None, :] + self._stride * np.arange(M)[:, None]]  # (dim, M, nz)
        Z = Z * durations[None, :, None] ** self._rpow[None, None, :]
        return np.einsum("na,dia->ind", self._E, Z)


class _PieceBasis:
    """The constant basis of one piece and where its local variables sit in ``x``.

    Local variable ``a`` of piece ``i`` (dimension ``d``) is
    ``x[d * per_dim + i * stride + offset[a]]``; its coefficient carries ``T_i^rpow[a]``.
    ``G = E^T H E`` gives piece ``i``'s cost ``T_i^(1-2q) sum_ab G_ab T_i^(r_a + r_b) z_a z_b``.
    """

    def __init__(self, shape: MinSnapShape) -> None:
        M, D, q = shape.pieces, shape.degree, shape.derivative
        N = D + 1
        nb = N - 2 * q
        self.stride = q + nb
        self.per_dim = (M + 1) * q + M * nb
        herm, bub = hermite_basis(D, q)
        self.E = np.hstack([herm, bub])  # N x nz: tau-coefficients of the piece's local variables
        self.nz = self.E.shape[1]
        self.offset = np.concatenate([np.arange(q), self.stride + np.arange(q), q + np.arange(nb)])
        self.rpow = np.concatenate([np.arange(q), np.arange(q), np.zeros(nb, int)])
        G = self.E.T @ cost_hessian(D, q) @ self.E
        G = (G + G.T) / 2  # exactly symmetric, so P's (a, b) and (b, a) entries are the same float
        G[np.abs(G) < 1e-12 * np.abs(G).max()] = 0.0
        self.G = G


class _Symbols:
    """The parameters (waypoints, durations, corridor bounds, end derivatives) and the variables."""

    def __init__(self, shape: MinSnapShape, n: int) -> None:
        import casadi as ca

        M, dim, K = shape.pieces, shape.dim, shape.samples_per_piece
        self.W = ca.SX.sym("W", (M + 1) * dim)
        self.T = ca.SX.sym("T", M)
        self.lo = ca.SX.sym("lo", M * K * dim)
        self.hi = ca.SX.sym("hi", M * K * dim)
        self.g0 = ca.SX.sym("g0", shape.start_order * dim)
        self.g1 = ca.SX.sym("g1", shape.end_order * dim)
        self.x = ca.SX.sym("x", n)


class _DurationPowers:
    """Row vectors ``T_i^e``, each power formed once."""

    def __init__(self, T, M: int) -> None:
        self._T, self._M = T, M
        self._powers: dict = {}

    def __call__(self, e: int, sl=slice(None)):
        import casadi as ca

        if e not in self._powers:
            self._powers[e] = ca.DM.ones(1, self._M) if e == 0 else self._T.T ** e
        return self._powers[e][:, sl]


def _cost_matrix(shape: MinSnapShape, basis: _PieceBasis, Tp: _DurationPowers, n: int):
    """P written out (no AD): ``P[d, i*stride+offset[a], i*stride+offset[b]] += 2 G_ab T_i^(1-2q+r_a+r_b)``.

    Even pieces share no knot, nor do odd ones: one duplicate-free triplet per parity, one addition.
    """
    import casadi as ca

    M, dim, q = shape.pieces, shape.dim, shape.derivative
    G, offset, rpow, stride, per_dim = basis.G, basis.offset, basis.rpow, basis.stride, basis.per_dim
    pairs = [(a_, b_) for a_ in range(basis.nz) for b_ in range(basis.nz) if G[a_, b_] != 0.0]
    P = 0
    for parity in (0, 1):
        pieces = np.arange(parity, M, 2)
        if pieces.size == 0:
            continue
        rows, cols, vals = [], [], []
        for a_, b_ in pairs:
            v = 2.0 * float(G[a_, b_]) * Tp(1 - 2 * q + int(rpow[a_] + rpow[b_]))[:, pieces.tolist()]
            for d in range(dim):
                rows.append(d * per_dim + offset[a_] + stride * pieces)
                cols.append(d * per_dim + offset[b_] + stride * pieces)
                vals.append(v)
        P = P + ca.SX.triplet(np.concatenate(rows).tolist(), np.concatenate(cols).tolist(),
                              ca.horzcat(*vals).T, n, n)
    return P


def _constraints(shape: MinSnapShape, basis: _PieceBasis, sym: _Symbols, Tp: _DurationPowers) -> tuple[list, list, list]:
    """Constraint expressions and their bounds, dimension by dimension.

    Per dimension, in this order: the knot positions, the given start and end
    derivatives, continuity above ``q - 1``, the corridor samples (see :func:`_position_rows`).
    """
    M, K, ks, ke = shape.pieces, shape.samples_per_piece, shape.start_order, shape.end_order
    stride, per_dim = basis.stride, basis.per_dim
    g: list = []
    lb: list = []
    ub: list = []
    for d in range(shape.dim):
        xd = sym.x[d * per_dim:(d + 1) * per_dim]
        Z = [xd[(basis.offset[a] + stride * np.arange(M)).tolist()].T for a in range(basis.nz)]  # 1 x M each
        Wd = sym.W[d * (M + 1):(d + 1) * (M + 1)]
        g.append(xd[(stride * np.arange(M + 1)).tolist()])  # positions y_{j,0}
        lb.append(Wd)
        ub.append(Wd)
        if ks:
            g.append(xd[list(range(1, ks + 1))])
            lb.append(sym.g0[d * ks:(d + 1) * ks])
            ub.append(sym.g0[d * ks:(d + 1) * ks])
        if ke:
            g.append(xd[[M * stride + r for r in range(1, ke + 1)]])
            lb.append(sym.g1[d * ke:(d + 1) * ke])
            ub.append(sym.g1[d * ke:(d + 1) * ke])
        if M > 1:
            _continuity(g, lb, ub, shape, basis, sym, Tp, Z)
        if K:
            g.append(_corridor_samples(shape, basis, Tp, Z))  # row s + K*i
            lb.append(sym.lo[d * M * K:(d + 1) * M * K])
            ub.append(sym.hi[d * M * K:(d + 1) * M * K])
    return g, lb, ub


def _continuity(g: list, lb: list, ub: list, shape: MinSnapShape, basis: _PieceBasis, sym: _Symbols,
                Tp: _DurationPowers, Z: list) -> None:
    """Append derivatives ``q..c`` equal across each knot (in normalized time, rho-scaled)."""
    import casadi as ca

    M, D, q, c = shape.pieces, shape.degree, shape.derivative, shape.continuity
    E, rpow = basis.E, basis.rpow
    rho = (sym.T[1:] / sym.T[:-1]).T  # 1 x (M-1)
    left, right = slice(0, M - 1), slice(1, M)
    for r in range(q, c + 1):
        e1 = derivative_row(D, r, 1.0) @ E
        e0 = derivative_row(D, r, 0.0) @ E
        expr = 0
        for a_ in range(basis.nz):
            if e1[a_] != 0.0:
                expr += float(e1[a_]) * Z[a_][:, left] * Tp(int(rpow[a_]), left) * rho ** (r / 2)
            if e0[a_] != 0.0:
                expr -= float(e0[a_]) * Z[a_][:, right] * Tp(int(rpow[a_]), right) * rho ** (-r / 2)
        g.append(expr.T)
        lb.append(ca.DM.zeros(M - 1))
        ub.append(ca.DM.zeros(M - 1))


def _corridor_samples(shape: MinSnapShape, basis: _PieceBasis, Tp: _DurationPowers, Z: list):
    """Positions at the ``K`` sample taus of every piece, as one column (row ``s + K * i``)."""
    import casadi as ca

    K, M = shape.samples_per_piece, shape.pieces
    VE = np.vander(corridor_sample_taus(K), shape.degree + 1, increasing=True) @ basis.E
    rows = []
    for s_ in range(K):
        row = 0
        for a_ in range(basis.nz):
            if VE[s_, a_] != 0.0:
                row += float(VE[s_, a_]) * Z[a_] * Tp(int(basis.rpow[a_]))
        rows.append(row)
    return ca.reshape(ca.vertcat(*rows), K * M, 1)


def _position_rows(shape: MinSnapShape) -> np.ndarray:
    """(dim, M+1) constraint rows of the knot positions ``y_{j,0}`` (a waypoint tolerance widens their bounds)."""
    M, q, c = shape.pieces, shape.derivative, shape.continuity
    rows_per_dim = (M + 1) + shape.start_order + shape.end_order + (c - q + 1) * max(M - 1, 0) + shape.samples_per_piece * M
    return np.arange(shape.dim)[:, None] * rows_per_dim + np.arange(M + 1)[None, :]


@lru_cache(maxsize=32)
def compiled_min_snap(shape: MinSnapShape) -> CompiledMinSnap:
    """The compiled formulation of ``shape`` (built on first use, then cached)."""
    return CompiledMinSnap(shape)
