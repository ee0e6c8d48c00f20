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
:math:`\\sigma^{(r)}(t) = T_i^{-r} d^r/d\\tau^r`. Variables are ordered dimension-major,
then ``y_0, b_0, y_1, b_1, ..., y_M``. The parameters are the (normalized) waypoints,
durations, corridor bounds and end derivatives; one :class:`casadi.Function` per
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
import time
from functools import lru_cache

import numpy as np
import scipy.sparse as sp

from mrfswarm.trajectory.corridor import sample_taus
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


def _sparse_dm(ca, a: np.ndarray):
    """A casadi DM holding only the structural nonzeros of ``a`` (so SX skips the zeros)."""
    a = np.where(np.abs(a) < 1e-14 * max(1.0, np.abs(a).max()), 0.0, a)  # exact zeros of the Hermite solve
    return ca.sparsify(ca.DM(np.atleast_2d(a)))


class CompiledMinSnap:
    """The compiled QP of one shape: evaluate it into a :class:`~solvers.qp.QPProblem`.

    Not thread-safe (one evaluation buffer per shape).
    """

    def __init__(self, shape: MinSnapShape) -> None:
        import casadi as ca

        t0 = time.perf_counter()
        self.shape = shape
        M, dim, D, q = shape.pieces, shape.dim, shape.degree, shape.derivative
        c, K, ks, ke = shape.continuity, shape.samples_per_piece, shape.start_order, shape.end_order
        N = D + 1
        nb = N - 2 * q
        stride = q + nb
        per_dim = (M + 1) * q + M * nb
        self.n = dim * per_dim
        W = ca.SX.sym("W", (M + 1) * dim)
        T = ca.SX.sym("T", M)
        lo = ca.SX.sym("lo", M * K * dim)
        hi = ca.SX.sym("hi", M * K * dim)
        g0 = ca.SX.sym("g0", ks * dim)
        g1 = ca.SX.sym("g1", ke * dim)
        x = ca.SX.sym("x", self.n)

        herm, bub = hermite_basis(D, q)
        Hm0 = _sparse_dm(ca, herm[:, :q])
        Hm1 = _sparse_dm(ca, herm[:, q:])
        Bm = _sparse_dm(ca, bub) if nb else None
        H = _sparse_dm(ca, cost_hessian(D, q))
        weight = T.T ** (1 - 2 * q)  # 1 x M
        powers = ca.DM(np.arange(q))
        Tpow = ca.repmat(T.T, q, 1) ** ca.repmat(powers, 1, M)  # q x M: T_i^r
        F0 = [_sparse_dm(ca, derivative_row(D, r, 0.0)) for r in range(D + 1)]
        F1 = [_sparse_dm(ca, derivative_row(D, r, 1.0)) for r in range(D + 1)]
        V = _sparse_dm(ca, np.vander(sample_taus(K), N, increasing=True)) if K else None
        rho = (T[1:] / T[:-1]).T if M > 1 else None  # 1 x (M-1)

        cost = 0
        g, lb, ub = [], [], []
        for d in range(dim):
            xd = x[d * per_dim:(d + 1) * per_dim]
            idx_y = np.arange(M + 1)[None, :] * stride + np.arange(q)[:, None]  # q x (M+1)
            Y = ca.reshape(xd[idx_y.T.ravel().tolist()], q, M + 1)  # column j = y_j
            C = ca.mtimes(Hm0, Y[:, :-1] * Tpow) + ca.mtimes(Hm1, Y[:, 1:] * Tpow)  # N x M
            if nb:
                idx_b = np.arange(M)[None, :] * stride + q + np.arange(nb)[:, None]
                C = C + ca.mtimes(Bm, ca.reshape(xd[idx_b.T.ravel().tolist()], nb, M))
            cost += ca.sum2(ca.sum1(C * ca.mtimes(H, C)) * weight)
            Wd = W[d * (M + 1):(d + 1) * (M + 1)]
            g.append(Y[0, :].T)
            lb.append(Wd)
            ub.append(Wd)
            if ks:
                g.append(Y[1:ks + 1, 0])
                lb.append(g0[d * ks:(d + 1) * ks])
                ub.append(g0[d * ks:(d + 1) * ks])
            if ke:
                g.append(Y[1:ke + 1, M])
                lb.append(g1[d * ke:(d + 1) * ke])
                ub.append(g1[d * ke:(d + 1) * ke])
            if M > 1:
                for r in range(q, c + 1):
                    expr = (ca.mtimes(F1[r], C[:, :-1]) * rho ** (r / 2) - ca.mtimes(F0[r], C[:, 1:]) * rho ** (-r / 2)).T
                    g.append(expr)
                    lb.append(ca.DM.zeros(M - 1))
                    ub.append(ca.DM.zeros(M - 1))
            if K:
                g.append(ca.reshape(ca.mtimes(V, C), K * M, 1))  # row s + K*i
                lb.append(lo[d * M * K:(d + 1) * M * K])
                ub.append(hi[d * M * K:(d + 1) * M * K])
        G = ca.vertcat(*g)
        P = ca.hessian(cost, x)[0]
        A = ca.jacobian(G, x)
        self.m = G.numel()
        self._fn = ca.Function("min_snap_qp", [W, T, lo, hi, g0, g1], [P, A, ca.vertcat(*lb), ca.vertcat(*ub)])
        sP, sA = self._fn.sparsity_out(0), self._fn.sparsity_out(1)
        self._P_pattern = (np.asarray(sP.row(), np.int32), np.asarray(sP.colind(), np.int32))
        self._A_pattern = (np.asarray(sA.row(), np.int32), np.asarray(sA.colind(), np.int32))
        self._nnz = (sP.nnz(), sA.nnz())
        self._buf, self._eval = self._fn.buffer()
        # numpy side of the basis, to turn a solution into tau-coefficients
        self._herm, self._bub = herm, bub
        self._stride, self._per_dim, self._nb = stride, per_dim, nb
        self.compile_time_s = time.perf_counter() - t0
        log.debug("compiled min-snap QP %s in %.3f s (n=%d, m=%d)", shape, self.compile_time_s, self.n, self.m)

    def evaluate(self, waypoints: np.ndarray, durations: np.ndarray, lower: np.ndarray | None,
                 upper: np.ndarray | None, start: np.ndarray, end: np.ndarray) -> QPProblem:
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
        """
        args = [
            np.ascontiguousarray(waypoints.T, dtype=float).reshape(-1),
            np.ascontiguousarray(durations, dtype=float),
            np.empty(0) if lower is None else np.ascontiguousarray(np.moveaxis(lower, 2, 0), dtype=float).reshape(-1),
            np.empty(0) if upper is None else np.ascontiguousarray(np.moveaxis(upper, 2, 0), dtype=float).reshape(-1),
            np.ascontiguousarray(start.T, dtype=float).reshape(-1),
            np.ascontiguousarray(end.T, dtype=float).reshape(-1),
        ]
        outs = [np.empty(self._nnz[0]), np.empty(self._nnz[1]), np.empty(self.m), np.empty(self.m)]
        for i, a in enumerate(args):
            self._buf.set_arg(i, memoryview(a))
        for i, o in enumerate(outs):
            self._buf.set_res(i, memoryview(o))
        self._eval()
        P = sp.csc_matrix((outs[0], *self._P_pattern), shape=(self.n, self.n))
        A = sp.csc_matrix((outs[1], *self._A_pattern), shape=(self.m, self.n))
        return QPProblem(P=P, q=np.zeros(self.n), A=A, l=outs[2], u=outs[3])

    def coefficients(self, x: np.ndarray, durations: np.ndarray) -> np.ndarray:
        """(M, D+1, dim) tau-coefficients (normalized units) of a solution ``x``.

        ``durations`` are the normalized durations the QP was evaluated with.
        """
        s = self.shape
        M, q, nb, stride = s.pieces, s.derivative, self._nb, self._stride
        X = np.asarray(x, dtype=float).reshape(s.dim, self._per_dim)
        knots = np.arange(M + 1)[:, None] * stride + np.arange(q)[None, :]
        y = X[:, knots]  # (dim, M+1, q)
        Tp = durations[:, None] ** np.arange(q)[None, :]  # (M, q)
        c = np.einsum("nr,dir->ind", self._herm[:, :q], y[:, :-1] * Tp[None])
        c += np.einsum("nr,dir->ind", self._herm[:, q:], y[:, 1:] * Tp[None])
        if nb:
            bidx = np.arange(M)[:, None] * stride + q + np.arange(nb)[None, :]
            c += np.einsum("nm,dim->ind", self._bub, X[:, bidx])
        return c


@lru_cache(maxsize=32)
def compiled_min_snap(shape: MinSnapShape) -> CompiledMinSnap:
    """The compiled formulation of ``shape`` (built on first use, then cached)."""
    return CompiledMinSnap(shape)
