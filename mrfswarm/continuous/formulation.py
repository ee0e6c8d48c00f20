"""The window problem of the continuous stage, formulated once with CasADi symbols.

Variables. Robot g's trajectory over the window's M steps is one polynomial piece of
degree D per step, written in the Hermite basis of
:mod:`mrfswarm.trajectory.formulation`: the variables are the derivatives
:math:`0..q-1` of the trajectory at every knot (shared by the two pieces that meet there,
so continuity up to order q - 1, jerk for min-snap, holds by construction) plus, for
D > 2q - 1, "bubble" coefficients per piece. Units: metres relative to the robot's
discrete position at the window start, and a time unit :math:`T_s` (the window's
geometric-mean step duration), so that every variable has the size of a position.

The symbolic piece (:class:`PieceMaps`, compiled once per degree and derivative). For a
piece of normalized duration :math:`\\tilde T` with local variables z, CasADi expresses

- the Bernstein control points of position, velocity, acceleration and jerk,
  :math:`K_r(\\tilde T)\\, z` (:mod:`mrfswarm.trajectory.bernstein`), linear in z;
- the snap cost :math:`\\tilde T^{1-2q} c^\\top H c = \\tfrac12 z^\\top H_c(\\tilde T) z`.

Their coefficients, as functions of :math:`\\tilde T` only, are the single source of the
window problem. The window (:class:`WindowFormulation`) is assembled from them by fixed
sparse maps: every nonzero of the cost matrix P and constraint matrix A is a linear
combination of those coefficients, ``P.data = S_P k(T)``, ``A.data = S_A k(T)``, with
``k(T)`` the stacked piece coefficients of the window's steps. The rows are

- the region of every robot and step: ``lower <= axes @ P_m <= upper`` for every
  control point (:mod:`mrfswarm.continuous.regions`);
- every relative safe corridor: ``n . (P_m^g - P_m^h) >= d_safe``;
- the limits: every velocity, acceleration and jerk control point (of each of
  ``LIMIT_PARTS`` equal sub-intervals of a piece: a linear map of the same variables) inside
  a regular 16-gon inscribed in the disc of radius ``v_max`` (``a_max``, ``j_max``), in
  space a 26-faced polytope inscribed in the ball (:func:`limit_polytope`), so the
  derivative's norm stays below the limit for all t;
- the window's ends: the start state (position and derivatives 1..q-1) and rest at the
  end position;
- where a piece spans several steps (``WindowSpec.merged``): the Taylor coefficients of
  orders q..D of the two pieces meeting at a merged knot are equal, so that they are one
  polynomial (:mod:`mrfswarm.continuous.merge_pieces`); every row above stays on each
  step's piece, which is then that polynomial's restriction to the step.

All region, corridor and limit rows are tightened by ``margin`` (metres, or a relative
``margin`` on limits) so that a solution within a solver's tolerance still satisfies the
untightened constraints that the certificate checks.

With the step durations fixed, ``k(T)`` is a number and the problem a QP for any backend
of :mod:`solvers.qp` (:meth:`WindowFormulation.qp`). With the durations as variables it
is an NLP: the optimal snap at durations T plus a weight times the window's duration,
minimized over T by Ipopt, each evaluation a QP and its gradient exact from the QP's
multipliers and the symbolic derivative ``dk/dT``
(:meth:`WindowFormulation.duration_gradient`). Durations are shared by all robots (one
time grid) and every constraint is indexed by step, not by time, so the constraints stay
valid whatever durations the NLP picks. This reduced space was chosen over one NLP in the
trajectory and the durations together (tried first): every point Ipopt visits is then a
solution of the window problem with all its lazily added rows, so the next window's
feasibility argument holds for whatever it returns, and Ipopt works on M variables, not
thousands (corridor10 with refinement: 28 s of planning instead of 403 s, makespan 25.1 s
instead of 33.2 s).
"""

from __future__ import annotations

import itertools
import logging
import math
import threading
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np
import scipy.sparse as sp

from mrfswarm.continuous.regions import Regions
from mrfswarm.trajectory.bernstein import difference_matrix, monomial_to_bernstein, subdivision_matrix
from mrfswarm.trajectory.formulation import hermite_basis
from mrfswarm.trajectory.polynomial import PiecewisePolynomial, cost_hessian, derivative_row, tau_to_time
from solvers.qp import QPProblem

log = logging.getLogger(__name__)

#: Derivative orders whose control points are bounded: velocity, acceleration, jerk.
LIMIT_ORDERS = (1, 2, 3)
#: Face directions of the limit polygon in the plane (one per pair of opposite faces): the regular 16-gon
#: inscribed in the disc, turned so that its vertices lie along the grid's eight move directions (the axes and
#: the diagonals) and its faces between them. A straight run along a row, column or diagonal may then fly at the
#: limit itself (and a tenth of it across: v_x + tan(pi/16) |v_y| <= L), and no direction less than
#: cos(pi/16) = 0.981 of it. The octagon used before had its faces normal to those eight directions: every
#: straight run was held to cos(pi/8) = 0.924 of v_max, under the fast profile's cruise, so in long runs that
#: profile failed for the lag it piled up. Measured with the flight-quality cases (wr.py runs, 2026-11-27, one
#: run each, against that octagon): 300 robots crossing 72.2 s -> 66.6 s of makespan in 36 s of planning
#: instead of 62 (the fast profile flew 12 of 27 windows, now most), trap 27.2 -> 25.9, forest 32.4 -> 31.4,
#: open50 38.0 -> 36.6, rooms 31.5 -> 30.4, clutter40 90.2 -> 90.2; the same 16-gon with faces normal to the
#: moves: clutter40 93.0, rooms 30.5, open50 37.7; the octagon turned the same way: clutter40 92.4, rooms 31.6.
POLYGON_DIRECTIONS = 8
POLYGON = np.stack([np.cos(np.pi * (np.arange(POLYGON_DIRECTIONS) + 0.5) / POLYGON_DIRECTIONS),
                    np.sin(np.pi * (np.arange(POLYGON_DIRECTIONS) + 0.5) / POLYGON_DIRECTIONS)], axis=1)
POLYGON_INNER = math.cos(math.pi / (2 * POLYGON_DIRECTIONS))


@lru_cache(maxsize=4)
def limit_polytope(dim: int) -> tuple[np.ndarray, float]:
    """The faces of the polytope that bounds a derivative's control points, and its inner radius.

    A control point v meets the limit L when :math:`|n_k \\cdot v| \\le \\rho L` for every
    direction :math:`n_k` (unit, rows of the first array): that polytope is inscribed in the
    ball of radius L (its vertices farthest out lie on it), so :math:`\\|v\\| \\le L`; the ball
    of radius :math:`\\rho L` (the second value) lies inside it. In the plane: the regular
    16-gon with vertices along the grid's moves (:data:`POLYGON`, :math:`\\rho = \\cos(\\pi/16)`). In space: the
    13 directions of the cube's faces, edges and corners (the 26-neighbourhood up to sign), whose
    polytope's farthest vertex :math:`x^*` is found by enumerating every three faces
    (:math:`\\rho = 1/\\|x^*\\| \\approx 0.8865`).
    """
    if dim == 2:
        return POLYGON, POLYGON_INNER
    if dim != 3:
        raise ValueError(f"limit_polytope: dim must be 2 or 3, got {dim}")
    cube = np.array(np.meshgrid(*[[-1.0, 0.0, 1.0]] * 3, indexing="ij")).reshape(3, -1).T
    first = cube[np.arange(len(cube)), np.argmax(cube != 0, axis=1)]
    dirs = cube[first > 0]  # one of each +-pair
    dirs = dirs / np.linalg.norm(dirs, axis=1, keepdims=True)
    planes = np.concatenate([dirs, -dirs])
    tri = np.array(list(itertools.combinations(range(len(planes)), 3)))
    A = planes[tri]  # (C, 3, 3)
    ok = np.abs(np.linalg.det(A)) > 1e-9
    x = np.linalg.solve(A[ok], np.ones((int(ok.sum()), 3, 1)))[..., 0]
    vertex = (x @ planes.T <= 1 + 1e-9).all(axis=1)
    far = float(np.linalg.norm(x[vertex], axis=1).max())
    return dirs, (1.0 / far) * (1 - 1e-12)
#: Each piece's derivatives are bounded on the control points of this many equal
#: sub-intervals: within 5 % of the true maximum of jerk for a rest-to-rest step, where
#: the whole piece's control points overestimate it eightfold.
LIMIT_PARTS = 4
#: Metres: a region whose rows, tightened, leave less than this is a hold (a robot held still at its cell,
#: :func:`~mrfswarm.continuous.regions.hold_regions`): in the window's first step its rows become equalities at
#: the box's centre, after it the piece's own variables are fixed at rest there instead (one row each), which a
#: solver meets exactly (an interior-point solver runs out of iterations in a box a few micrometres wide).
HOLD_WIDTH = 1e-4


class PieceMaps:
    """The symbolic piece: control points and cost coefficients as functions of its duration.

    Parameters
    ----------
    degree, derivative
        Polynomial degree D and minimized derivative q (D >= 2q - 1, D >= 3).
    parts
        Derivative control points are those of this many equal sub-intervals.

    Attributes
    ----------
    nz
        Local variables per piece and dimension: 2q knot derivatives and D + 1 - 2q bubbles.
    offset
        (nz,) position of each local variable relative to the piece's first variable (the
        layout of :mod:`mrfswarm.trajectory.formulation`: y_j, b_j, y_{j+1}).
    rpow
        (nz,) derivative order of each local variable (0 for bubbles).
    size
        Length of one piece's coefficient vector ``k``.
    """

    def __init__(self, degree: int, derivative: int, parts: int = 4) -> None:
        import casadi as ca

        D, q = degree, derivative
        if D < max(3, 2 * q - 1):
            raise ValueError(f"degree {D} must be >= max(3, 2q - 1) = {max(3, 2 * q - 1)}")
        herm, bub = hermite_basis(D, q)
        self.degree, self.derivative = D, q
        self.E = np.hstack([herm, bub])
        self.nz = self.E.shape[1]
        nb = self.nz - 2 * q
        self.stride = q + nb
        self.offset = np.concatenate([np.arange(q), self.stride + np.arange(q), q + np.arange(nb)])
        self.rpow = np.concatenate([np.arange(q), np.arange(q), np.zeros(nb, dtype=int)])
        T = ca.SX.sym("T")
        z = ca.SX.sym("z", self.nz)
        scale = ca.vertcat(*[T ** int(p) for p in self.rpow])
        c = ca.mtimes(ca.DM(self.E), scale * z)
        P = ca.mtimes(ca.DM(monomial_to_bernstein(D)), c)
        blocks, self.rows, self.k_offset = [], [], []
        start = 0
        for r in range(4):
            Dr = difference_matrix(D, r) if r == 0 else subdivision_matrix(D - r, parts) @ difference_matrix(D, r)
            Kr = ca.densify(ca.jacobian(ca.mtimes(ca.DM(Dr), P) / T**r, z))
            blocks.append(ca.vec(Kr))
            self.rows.append(Dr.shape[0])
            self.k_offset.append(start)
            start += Dr.shape[0] * self.nz
        # Taylor coefficients q..D at tau = 0 and tau = 1 (the r-th time derivative over r!): two pieces that
        # meet in them (and in 0..q-1, shared knot variables) are one polynomial (merge_pieces)
        self.taylor_orders = D + 1 - q
        taylor = ca.vertcat(*[ca.mtimes(ca.DM(derivative_row(D, r, tau)[None, :] / math.factorial(r)), c) / T**r
                              for tau in (0.0, 1.0) for r in range(q, D + 1)])
        blocks.append(ca.vec(ca.densify(ca.jacobian(taylor, z))))
        self.t_offset = start
        start += 2 * self.taylor_orders * self.nz
        cost = T ** (1 - 2 * q) * ca.mtimes([c.T, ca.DM(cost_hessian(D, q)), c])
        Hc = ca.densify(ca.hessian(cost, z)[0])
        blocks.append(ca.vec(Hc))
        self.h_offset = start
        self.size = start + self.nz * self.nz
        flat = ca.vertcat(*blocks)
        self.function = ca.Function("bernstein_piece", [T], [flat])
        self.derivative_function = ca.Function("bernstein_piece_dT", [T], [ca.jacobian(flat, T)])
        self._maps: dict[int, Any] = {}  # casadi.Function, per window length
        self._dmaps: dict[int, Any] = {}
        self._lock = threading.Lock()
        # structural nonzeros: exact zeros at two unrelated durations are zeros for all
        k = np.asarray(self.function(0.73)).ravel() != 0
        k |= np.asarray(self.function(1.61)).ravel() != 0
        self.masks = [k[o:o + rows * self.nz].reshape(self.nz, rows).T for o, rows in zip(self.k_offset, self.rows)]
        self.h_mask = k[self.h_offset:].reshape(self.nz, self.nz)
        self.t_mask = k[self.t_offset:self.h_offset].reshape(self.nz, 2 * self.taylor_orders).T

    def mapped(self, M: int):
        """``function`` mapped over M pieces (cached)."""
        with self._lock:
            if M not in self._maps:
                self._maps[M] = self.function.map(M)
            return self._maps[M]

    def evaluate(self, durations: np.ndarray) -> np.ndarray:
        """The window's stacked coefficients ``k`` for normalized ``durations`` (M,), plus a final 1."""
        d = np.asarray(durations, dtype=float).reshape(1, -1)
        out = np.asarray(self.mapped(d.shape[1])(d))  # (size, M)
        return np.concatenate([out.ravel(order="F"), [1.0]])

    def evaluate_derivative(self, durations: np.ndarray) -> np.ndarray:
        """(M, size): d k / d T of each piece's coefficients at normalized ``durations``."""
        d = np.asarray(durations, dtype=float).reshape(1, -1)
        M = d.shape[1]
        with self._lock:
            if M not in self._dmaps:
                self._dmaps[M] = self.derivative_function.map(M)
            fn = self._dmaps[M]
        return np.asarray(fn(d)).T

    def k_index(self, piece, order: int, m, a):
        """Index into ``k`` of control point m's coefficient of local variable a (order r)."""
        return piece * self.size + self.k_offset[order] + a * self.rows[order] + m

    def h_index(self, piece, a, b):
        """Index into ``k`` of the cost coefficient (a, b) (symmetric: the lower pair is used)."""
        lo, hi = np.minimum(a, b), np.maximum(a, b)
        return piece * self.size + self.h_offset + hi * self.nz + lo

    def t_index(self, piece, end, order, a):
        """Index into ``k`` of local variable a's coefficient in the Taylor coefficient ``order`` (q..D) at
        the piece's start (``end`` 0) or end (``end`` 1)."""
        row = end * self.taylor_orders + order - self.derivative
        return piece * self.size + self.t_offset + a * 2 * self.taylor_orders + row

    def tau_coefficients(self, z: np.ndarray, durations: np.ndarray) -> np.ndarray:
        """(M, D+1, dim) tau-coefficients from local variables ``z`` (M, nz, dim) and durations (M,)."""
        scale = durations[:, None] ** self.rpow[None, :]
        return np.einsum("ka,ma,mad->mkd", self.E, scale, z)


@lru_cache(maxsize=8)
def piece_maps(degree: int, derivative: int, parts: int = LIMIT_PARTS) -> PieceMaps:
    """The compiled :class:`PieceMaps` of a degree, derivative and subdivision (built on first use)."""
    return PieceMaps(degree, derivative, parts)


@dataclass(frozen=True)
class WindowSpec:
    """Everything one window problem depends on, in plain arrays (picklable).

    Attributes
    ----------
    degree, derivative
        Polynomial degree and minimized derivative.
    regions
        The robots' regions over the window's M steps (shape (M, G, ...)).
    pair_step, pair_first, pair_second, pair_normal
        Relative safe corridors: step within the window, local robot indices, unit normal.
    distance
        Safety distance (metres).
    start
        (G, q, dim) physical derivatives 0..q-1 at the window's start (positions absolute).
    end
        (G, dim) where each robot comes to rest at the window's end.
    origin
        (G, dim) the robots' discrete positions at the window's start (the local frame).
    limits
        (v_max, a_max, j_max).
    time_scale
        The time unit T_s (seconds).
    margin
        Tightening of region and corridor rows (metres); limits are tightened by the
        same relative amount.
    slack
        Metres kept free inside every region and corridor row besides ``margin``: room for
        an exporter's rounding (the Crazyflie's compressed format moves control points by
        up to about 2 mm), which the certificate of the rounded flight then still proves.
    limit_mask
        (M, G, 3) bool: which (step, robot, derivative order) get limit rows (None: all),
        or (M, G, 3, F): which faces of the limit polytope (:func:`limit_polytope`) each
        gets, or (M, G, 3, F, LIMIT_PARTS): which faces on which of the piece's equal parts
        (the control points of that part only). The window loop adds them lazily, where a
        solution without them exceeds a limit.
    merged
        (M - 1,) bool: the pieces of steps j and j + 1 are one polynomial (every robot's;
        :mod:`mrfswarm.continuous.merge_pieces`). None: no piece spans two steps.
    creep
        (M, G, dim) m/s: where not zero, every velocity control point of robot g's piece in
        step j has at least the norm of ``creep[j, g]`` along its direction, so the robot moves
        that way at least that fast throughout the step (a wait flown as a slow drift rather
        than a stop; a choice of the flight, not a safety row). None: no such rows.
    """

    degree: int
    derivative: int
    regions: Regions
    pair_step: np.ndarray
    pair_first: np.ndarray
    pair_second: np.ndarray
    pair_normal: np.ndarray
    distance: float
    start: np.ndarray
    end: np.ndarray
    origin: np.ndarray
    limits: tuple[float, float, float]
    time_scale: float
    margin: float = 1e-6
    slack: float = 0.0
    limit_mask: np.ndarray | None = None
    merged: np.ndarray | None = None
    creep: np.ndarray | None = None
    unit_merge_rows: bool = False

    @property
    def steps(self) -> int:
        return self.regions.steps

    @property
    def robots(self) -> int:
        return self.regions.robots


def _sparse_map(rows: np.ndarray, cols: np.ndarray, kidx: np.ndarray, coef: np.ndarray, shape: tuple[int, int],
                n_k: int) -> tuple[np.ndarray, np.ndarray, sp.csr_matrix]:
    """CSC pattern of a matrix whose entry (rows[e], cols[e]) sums coef[e] * k[kidx[e]], and the map k -> data.

    Entries that share a position are summed (sorting by position: O(nnz log nnz)).
    """
    key = cols.astype(np.int64) * shape[0] + rows.astype(np.int64)
    uniq, inv = np.unique(key, return_inverse=True)
    indices = (uniq % shape[0]).astype(np.int32)
    indptr = np.concatenate([[0], np.cumsum(np.bincount(uniq // shape[0], minlength=shape[1]))]).astype(np.int32)
    S = sp.csr_matrix((coef, (inv, kidx)), shape=(len(uniq), n_k))
    return indices, indptr, S


def _distinct_sparse_map(rows: np.ndarray, cols: np.ndarray, kidx: np.ndarray, coef: np.ndarray,
                         shape: tuple[int, int], n_k: int) -> tuple[np.ndarray, np.ndarray, sp.csr_matrix]:
    """:func:`_sparse_map` of entries at distinct positions (the constraint matrix), in linear time.

    SciPy's conversion to CSC (a counting sort) orders the entries: stored as values, their
    indices come out as the permutation. Entries that do share a position (not expected)
    take the general route.
    """
    nnz = len(rows)
    order = sp.csc_matrix((np.arange(1, nnz + 1, dtype=float), (rows, cols)), shape=shape)
    if order.nnz != nnz:
        return _sparse_map(rows, cols, kidx, coef, shape, n_k)
    order.sort_indices()
    perm = order.data.astype(np.int64) - 1
    S = sp.csr_matrix((coef[perm], kidx[perm], np.arange(nnz + 1)), shape=(nnz, n_k))
    return order.indices.astype(np.int32), order.indptr.astype(np.int32), S


@lru_cache(maxsize=32)
def _block_cost_map(degree: int, derivative: int, steps: int, per_dim: int) -> tuple[np.ndarray, np.ndarray, sp.csr_matrix]:
    """The cost's map (:func:`_sparse_map`) of one robot's one coordinate: every block of P is this one."""
    pm = piece_maps(degree, derivative)
    J, Aa, Bb = np.ix_(np.arange(steps), np.arange(pm.nz), np.arange(pm.nz))
    keep = np.broadcast_to(pm.h_mask[Aa, Bb], (steps, pm.nz, pm.nz))
    col_a, col_b = J * pm.stride + pm.offset[Aa], J * pm.stride + pm.offset[Bb]
    return _sparse_map(np.broadcast_to(col_a, keep.shape)[keep], np.broadcast_to(col_b, keep.shape)[keep],
                       np.broadcast_to(pm.h_index(J, Aa, Bb), keep.shape)[keep], np.ones(int(keep.sum())),
                       (per_dim, per_dim), steps * pm.size + 1)


def _block_diagonal_map(block: tuple[np.ndarray, np.ndarray, sp.csr_matrix],
                        copies: int) -> tuple[np.ndarray, np.ndarray, sp.csr_matrix]:
    """The map of a block-diagonal matrix of ``copies`` equal blocks (diagonal blocks of ``block``'s size)."""
    indices, indptr, S = block
    size, nnz = len(indptr) - 1, len(indices)
    shift = np.arange(copies)
    full_indices = (indices[None, :] + size * shift[:, None]).ravel().astype(np.int32)
    full_indptr = np.concatenate([(indptr[None, :-1] + nnz * shift[:, None]).ravel(), [nnz * copies]]).astype(np.int32)
    S_full = sp.csr_matrix((np.tile(S.data, copies), np.tile(S.indices, copies),
                            np.concatenate([(S.indptr[None, :-1] + S.nnz * shift[:, None]).ravel(), [S.nnz * copies]])),
                           shape=(nnz * copies, S.shape[1]))
    return full_indices, full_indptr, S_full


class WindowFormulation:
    """The window problem of one group of robots, assembled once per window.

    Parameters
    ----------
    spec
        The window's data.
    """

    def __init__(self, spec: WindowSpec) -> None:
        self.spec = spec
        self._merge_rows = (0, 0)
        pm = self.maps = piece_maps(spec.degree, spec.derivative)
        # the last durations' coefficients, one tuple (read and replaced whole: a cached formulation may serve
        # two threads at once)
        self._k_last: tuple[bytes, np.ndarray] = (b"", np.zeros(0))
        self._gradient_maps: list[tuple[np.ndarray, ...]] | None = None  # duration_gradient's, on first use
        M, G, D, q, nz = spec.steps, spec.robots, spec.degree, spec.derivative, pm.nz
        self.per_dim = (M + 1) * pm.stride - (pm.stride - q)  # y_0, b_0, ..., y_M
        dim = self.dim = spec.regions.axes.shape[-1]
        self.n = dim * G * self.per_dim
        n_k = M * pm.size + 1
        const = M * pm.size
        Ts = spec.time_scale
        reg = spec.regions
        origin = np.asarray(spec.origin, dtype=float)
        rows: list[np.ndarray] = []
        cols: list[np.ndarray] = []
        kidx: list[np.ndarray] = []
        coef: list[np.ndarray] = []
        lo: list[np.ndarray] = []
        hi: list[np.ndarray] = []
        n_rows = 0

        def col(g, d, j, a):
            return (g * dim + d) * self.per_dim + j * pm.stride + pm.offset[a]

        def add(shape_rows: tuple, r_idx, c_idx, k_idx, cf, keep, lower, upper):
            nonlocal n_rows
            full = np.broadcast_shapes(*(np.shape(v) for v in (r_idx, c_idx, k_idx, cf, keep)))
            keep = np.broadcast_to(keep, full)
            for lst, v in ((rows, r_idx), (cols, c_idx), (kidx, k_idx), (coef, cf)):
                lst.append(np.broadcast_to(v, keep.shape)[keep])
            rows[-1] = rows[-1] + n_rows
            lo.append(np.broadcast_to(lower, shape_rows).ravel())
            hi.append(np.broadcast_to(upper, shape_rows).ravel())
            n_rows += int(np.prod(shape_rows))

        # regions: rows (j, g, m, k); entries over (d, a)
        J, Gi, Mm, Kk, Dd, Aa = np.ix_(np.arange(M), np.arange(G), np.arange(D + 1), np.arange(dim),
                                       np.arange(dim), np.arange(nz))
        shape_r = (M, G, D + 1, dim)
        ridx = ((J * G + Gi) * (D + 1) + Mm) * dim + Kk
        cf = reg.axes[J, Gi, Kk, Dd]
        shift = np.einsum("mgka,ga->mgk", reg.axes, origin)[:, :, None, :]
        r_lo = reg.lower[:, :, None, :] - shift + spec.margin + spec.slack
        r_hi = reg.upper[:, :, None, :] - shift - spec.margin - spec.slack
        hold = r_hi - r_lo < HOLD_WIDTH  # a held robot's box (regions.hold_regions): equalities at its centre
        # a held step after the window's first: its piece's own variables (both knots' derivatives and its
        # bubbles) fixed at rest at the centre, one unit row each, instead of its D + 1 control points' equalities
        # (whose coefficients depend on the duration): the same constraint, on which piqp needed fewer iterations
        # (seven 40-robot clutter maps: the same flights but on three, with stops per robot 0.40 -> 0.28,
        # 0.38 -> 0.25, 0.08 -> 0.03 and 0.23 -> 0.30)
        held = hold[:, :, 0].all(axis=-1)  # (M, G)
        held[0] = False
        if hold.any():
            mid = 0.5 * (r_lo + r_hi)
            r_lo, r_hi = np.where(hold, mid, r_lo), np.where(hold, mid, r_hi)
            r_lo = np.where(held[:, :, None, None], -np.inf, r_lo)
            r_hi = np.where(held[:, :, None, None], np.inf, r_hi)
        add(shape_r, ridx, col(Gi, Dd, J, Aa), pm.k_index(J, 0, Mm, Aa), cf,
            pm.masks[0][Mm, Aa] & (cf != 0) & ~held[J, Gi], r_lo, r_hi)
        # limits: rows (j, g, m, face) per order, the faces switched on for (j, g) only
        faces, inner = limit_polytope(dim)
        nf = len(faces)
        mask = np.ones((M, G, 3, nf), dtype=bool) if spec.limit_mask is None else np.asarray(spec.limit_mask)
        if mask.ndim == 3:  # per (step, robot, order): every face
            mask = np.broadcast_to(mask[..., None], mask.shape + (nf,))
        if mask.ndim == 4:  # per face: every part of the piece
            mask = np.broadcast_to(mask[..., None], mask.shape + (LIMIT_PARTS,))
        for r, lim in zip(LIMIT_ORDERS, spec.limits):
            Rp = pm.rows[r] // LIMIT_PARTS  # control points per part
            bound = lim * Ts**r * inner * (1 - spec.margin)
            slots = mask[:, :, r - 1].reshape(M, G, nf * LIMIT_PARTS)  # (face, part), face-major
            on = slots.any(axis=-1)
            J, Gi = np.nonzero(on)  # row-major, as the rows are numbered
            slots_on = slots[on]  # (P, nf * parts)
            na = slots_on.sum(axis=1)
            base = np.concatenate([[0], np.cumsum(Rp * na)[:-1]]).astype(np.int64)
            rank = np.cumsum(slots_on, axis=1) - 1
            I, S = np.nonzero(slots_on)  # (pair, slot) in order
            Kf, part = S // LIMIT_PARTS, S % LIMIT_PARTS
            Mm, Dd, Aa = np.ix_(np.arange(Rp), np.arange(dim), np.arange(nz))
            Jp, Gp = J[I][:, None, None, None], Gi[I][:, None, None, None]
            ridx = (base[I] + rank[I, S])[:, None, None, None] + Mm[None] * na[I][:, None, None, None]
            cp = part[:, None, None, None] * Rp + Mm[None]  # the control point's index in the piece
            cf = faces[Kf][:, None, :, None]
            add((int(Rp * na.sum()),), ridx, col(Gp, Dd[None], Jp, Aa[None]), pm.k_index(Jp, r, cp, Aa[None]), cf,
                pm.masks[r][cp, Aa[None]] & (cf != 0), -bound, bound)
        # creeping: rows (j, g, m) for the pieces that keep moving, u . V_m >= |creep| (time-normalized)
        if spec.creep is not None:
            speed = np.linalg.norm(spec.creep, axis=-1)  # (M, G)
            J, Gi = np.nonzero(speed > 0)
            if len(J):
                R = pm.rows[1]
                u = spec.creep[J, Gi] / speed[J, Gi][:, None]  # (P, dim)
                Pi, Mm, Dd, Aa = np.ix_(np.arange(len(J)), np.arange(R), np.arange(dim), np.arange(nz))
                cf = u[Pi, Dd]
                add((len(J), R), Pi * R + Mm, col(Gi[Pi], Dd, J[Pi], Aa), pm.k_index(J[Pi], 1, Mm, Aa), cf,
                    pm.masks[1][Mm, Aa] & (cf != 0), (speed[J, Gi] * Ts * (1 + spec.margin))[:, None], np.inf)
        # relative safe corridors: rows (pair, m)
        P = len(spec.pair_step)
        if P:
            pj, pf, ps, nrm = spec.pair_step, spec.pair_first, spec.pair_second, spec.pair_normal
            Pi, Mm, Dd, Aa = np.ix_(np.arange(P), np.arange(D + 1), np.arange(dim), np.arange(nz))
            ridx = Pi * (D + 1) + Mm
            keep = pm.masks[0][Mm, Aa] & (nrm[Pi, Dd] != 0)
            offs = ((origin[pf] - origin[ps]) * nrm).sum(-1)[:, None]
            first_rows = n_rows
            add((P, D + 1), ridx, col(pf[Pi], Dd, pj[Pi], Aa), pm.k_index(pj[Pi], 0, Mm, Aa), nrm[Pi, Dd], keep,
                spec.distance + spec.margin + spec.slack - offs, np.inf)
            n_rows = first_rows  # the second robot's entries share the same rows
            add((0,), ridx, col(ps[Pi], Dd, pj[Pi], Aa), pm.k_index(pj[Pi], 0, Mm, Aa), -nrm[Pi, Dd], keep, 0.0, 0.0)
            n_rows = first_rows + P * (D + 1)
        # merged pieces: pieces j and j + 1 share their Taylor coefficients q..D at the knot between them
        # (0..q-1 they share by construction), so they are one polynomial; rows (knot, g, d, order)
        J = np.flatnonzero(spec.merged) if spec.merged is not None else np.zeros(0, dtype=int)
        if len(J):
            nt = pm.taylor_orders
            Jm, Gi, Dd, Rr, Aa = np.ix_(np.arange(len(J)), np.arange(G), np.arange(dim), np.arange(nt), np.arange(nz))
            ridx = ((Jm * G + Gi) * dim + Dd) * nt + Rr
            first_rows = n_rows
            add((len(J), G, dim, nt), ridx, col(Gi, Dd, J[Jm], Aa), pm.t_index(J[Jm], 1, q + Rr, Aa), 1.0,
                pm.t_mask[nt + Rr, Aa], 0.0, 0.0)
            n_rows = first_rows  # the next piece's entries share the same rows
            add((0,), ridx, col(Gi, Dd, J[Jm] + 1, Aa), pm.t_index(J[Jm] + 1, 0, q + Rr, Aa), -1.0,
                pm.t_mask[Rr, Aa], 0.0, 0.0)
            n_rows = first_rows + len(J) * G * dim * nt
            self._merge_rows = (first_rows, n_rows)
        # ends: the start state and rest at the end
        ends_fixed = np.concatenate([
            ((np.arange(G)[:, None, None] * dim + np.arange(dim)[None, None, :]) * self.per_dim + knot * pm.stride
             + np.arange(q)[None, :, None]).ravel() for knot in (0, M)])
        if held.any():  # the held pieces' variables not already fixed by the ends
            Jh, Gh = np.nonzero(held)
            centre = np.einsum("pkd,pk->pd", reg.axes[Jh, Gh], mid[Jh, Gh, 0])  # (H, dim), from the origin
            local = np.arange(pm.stride + q)  # knot j's derivatives, piece j's bubbles, knot j + 1's derivatives
            c_idx = ((Gh[:, None, None] * dim + np.arange(dim)[None, :, None]) * self.per_dim
                     + Jh[:, None, None] * pm.stride + local[None, None, :])  # (H, dim, stride + q)
            val = np.where((local == 0) | (local == pm.stride), centre[:, :, None], 0.0)
            c_idx, first = np.unique(c_idx.ravel(), return_index=True)
            val = val.ravel()[first]
            free = ~np.isin(c_idx, ends_fixed)
            c_idx, val = c_idx[free], val[free]
            add((len(c_idx),), np.arange(len(c_idx)), c_idx, const, 1.0, True, val, val)
        start = np.asarray(spec.start, dtype=float).copy()  # (G, q, dim)
        start[:, 0] -= origin
        start *= (Ts ** np.arange(q))[None, :, None]
        end = np.zeros_like(start)
        end[:, 0] = np.asarray(spec.end, dtype=float) - origin
        for knot, val in ((0, start), (M, end)):
            Gi, Rr, Dd = np.ix_(np.arange(G), np.arange(q), np.arange(dim))
            c_idx = (Gi * dim + Dd) * self.per_dim + knot * pm.stride + Rr
            add((G, q, dim), ((Gi * q + Rr) * dim + Dd), c_idx, const, 1.0, True, val, val)
        self._fixed = ends_fixed
        self._fixed_values = np.concatenate([start.ravel(), end.ravel()])
        self.m = n_rows
        rows_a, cols_a = np.concatenate(rows), np.concatenate(cols)
        self._A = _distinct_sparse_map(rows_a, cols_a, np.concatenate(kidx), np.concatenate(coef), (self.m, self.n), n_k)
        self.l, self.u = np.concatenate(lo), np.concatenate(hi)
        # cost: one block per robot and coordinate, all alike (the symmetric piece Hessians along its steps)
        self._P = _block_diagonal_map(_block_cost_map(D, q, M, self.per_dim), dim * G)

    # ------------------------------------------------------------------ QP
    def _k(self, durations: np.ndarray) -> np.ndarray:
        """The pieces' coefficients at ``durations`` (the last ones kept: a solve asks for the QP, then the costs)."""
        key = np.asarray(durations, dtype=float).tobytes()
        last = self._k_last
        if last[0] != key:
            last = self._k_last = (key, self.maps.evaluate(self.normalized(durations)))
        return last[1]

    def normalized(self, durations: np.ndarray) -> np.ndarray:
        """Durations (seconds) in the window's time unit."""
        return np.asarray(durations, dtype=float) / self.spec.time_scale

    def qp(self, durations: np.ndarray) -> QPProblem:
        """The QP for step ``durations`` (seconds, (M,))."""
        k = self._k(durations)
        (ai, ap, SA), (pi, pp, SP) = self._A, self._P
        A = sp.csc_matrix((SA @ k, ai, ap), shape=(self.m, self.n))
        scale = self._row_scale(A)
        if scale is not None:
            A = sp.csc_matrix((A.data * scale[A.indices], A.indices, A.indptr), shape=A.shape)
        P = sp.csc_matrix((SP @ k, pi, pp), shape=(self.n, self.n))
        return QPProblem(P=P, q=np.zeros(self.n), A=A, l=self.l, u=self.u)

    def _row_scale(self, A: sp.csc_matrix) -> np.ndarray | None:
        """(m,) the rows' factors in :meth:`qp` with ``spec.unit_merge_rows``: the merge rows (= 0) to unit norm, so
        that they are met to the solver's tolerance whatever the durations (in the short time unit of
        ``receding_horizon.MERGED_TIME_UNIT``, at a witness's long steps their order-7 coefficients shrank, and a
        block's projection moved it 0.019 m); the others 1. None without merge rows or the flag."""
        lo, hi = self._merge_rows
        if hi <= lo or not self.spec.unit_merge_rows:
            return None
        norm = np.sqrt(np.bincount(A.indices, A.data**2, minlength=self.m))
        scale = np.ones(self.m)
        scale[lo:hi] = 1.0 / np.maximum(norm[lo:hi], 1e-300)
        return scale

    def objective(self, x: np.ndarray, durations: np.ndarray) -> float:
        """The snap integral (physical units) of solution ``x`` at ``durations``."""
        k = self._k(durations)
        pi, pp, SP = self._P
        P = sp.csc_matrix((SP @ k, pi, pp), shape=(self.n, self.n))
        return float(0.5 * x @ (P @ x)) * self.spec.time_scale ** (1 - 2 * self.spec.derivative)

    def robot_objectives(self, x: np.ndarray, durations: np.ndarray) -> np.ndarray:
        """(G,) each robot's snap integral (physical units) in solution ``x``."""
        k = self._k(durations)
        pi, pp, SP = self._P
        P = sp.csc_matrix((SP @ k, pi, pp), shape=(self.n, self.n))
        per_var = 0.5 * x * (P @ x)  # P is block diagonal per robot
        scale = self.spec.time_scale ** (1 - 2 * self.spec.derivative)
        return per_var.reshape(self.spec.robots, -1).sum(axis=1) * scale

    def duration_gradient(self, x: np.ndarray, y: np.ndarray, durations: np.ndarray) -> np.ndarray:
        """(G, M) each robot's share of d(snap integral at the optimum)/d(step duration), physical units.

        The envelope theorem: with ``x`` optimal and ``y`` its multipliers (``P x + A' y =
        0`` on the free directions), the optimal value's derivative in a duration is the
        Lagrangian's, :math:`\tfrac12 x^\top P_T x + y^\top A_T x`; ``P_T`` and ``A_T``
        come from the symbolic piece's derivative in its duration. Each nonzero is credited
        to the robot of its column, so the shares add up to the window's gradient (exact
        where the active set does not change).
        """
        spec, pm = self.spec, self.maps
        M, G = spec.steps, spec.robots
        scale = None
        if self.spec.unit_merge_rows:  # the matrix rebuilt only where the QP scaled rows (not on every gradient)
            ai, ap, SA = self._A
            scale = self._row_scale(sp.csc_matrix((SA @ self._k(durations), ai, ap), shape=(self.m, self.n)))
        if scale is not None:  # the multipliers of the scaled merge rows, for the unscaled rows' derivatives (the
            y = y * scale  # rows are 0 at a solution, so their factors' own derivative adds nothing)
        dk = pm.evaluate_derivative(self.normalized(durations)).ravel()  # (M * size,): d k / d T_j, piece j's block
        if self._gradient_maps is None:
            self._gradient_maps = [self._gradient_map(*m) for m in (self._A, self._P)]
        out = np.zeros(G * M)
        for (idx, cols, starts, k, coef, rows, slot), half in zip(self._gradient_maps, (False, True)):
            w = (0.5 * x[idx] if half else y[idx]) * x[cols]  # the Lagrangian's weight of each nonzero
            # each nonzero's derivative in each of its pieces' durations, credited to the robot of its column:
            # summed in the order of the sparse products credit @ (S @ dK), to the last bit
            dnz = np.add.reduceat(coef * dk[k], starts) if len(k) else np.zeros(0)
            out += np.bincount(slot, w[rows] * dnz, minlength=G * M)
        # normalized -> physical: J = Ts^(1-2q) J~ and T~ = T / Ts
        return out.reshape(G, M) * spec.time_scale ** (-2 * spec.derivative)

    def _gradient_map(self, idx: np.ndarray, ptr: np.ndarray, S) -> tuple[np.ndarray, ...]:
        """The terms of :meth:`duration_gradient` for one matrix map ``(indices, indptr, S)``: each nonzero's row
        ``idx`` and column; S's entries that depend on a piece's duration (their coefficient index ``k`` and
        value), grouped by nonzero and piece (a cost entry of a knot's variables has two pieces) in their
        stored order; where each group starts, its nonzero and the (robot, step) it is credited to."""
        M, size = self.spec.steps, self.maps.size
        cols = np.repeat(np.arange(len(ptr) - 1), np.diff(ptr))
        S = S.tocsr()
        entry = np.repeat(np.arange(S.shape[0]), np.diff(S.indptr))
        k = S.indices.astype(np.int64)
        keep = k < M * size  # the constant (last) coefficient has no derivative
        entry, k, coef = entry[keep], k[keep], S.data[keep]
        group = entry * M + k // size
        order = np.argsort(group, kind="stable")
        group, k, coef = group[order], k[order], coef[order]
        starts = np.flatnonzero(np.r_[True, group[1:] != group[:-1]]) if len(group) else np.zeros(0, dtype=np.int64)
        rows, piece = np.divmod(group[starts], M)
        slot = (cols[rows] // (self.dim * self.per_dim)) * M + piece
        return idx, cols, starts, k, coef, rows, slot

    def exact_ends(self, x: np.ndarray) -> np.ndarray:
        """``x`` with its start state and end rest set exactly (a solver meets them only to tolerance)."""
        x = np.array(x, dtype=float)
        x[self._fixed] = self._fixed_values
        return x

    # ------------------------------------------------------------------ variables
    def unpack(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Physical knot derivatives (G, M+1, q, dim) (positions absolute) and bubbles (G, M, nb, dim)."""
        spec, pm = self.spec, self.maps
        M, G, q = spec.steps, spec.robots, spec.derivative
        X = np.asarray(x, dtype=float).reshape(G, self.dim, self.per_dim)
        full = np.concatenate([X, np.zeros((G, self.dim, pm.stride - q))], axis=2).reshape(G, self.dim, M + 1,
                                                                                           pm.stride)
        Y = full[..., :q].transpose(0, 2, 3, 1) / (spec.time_scale ** np.arange(q))[None, None, :, None]
        Y[:, :, 0] += np.asarray(spec.origin)[:, None, :]
        B = full[:, :, :M, q:].transpose(0, 2, 3, 1)
        return Y, B

    def pack(self, Y: np.ndarray, B: np.ndarray) -> np.ndarray:
        """The inverse of :meth:`unpack`."""
        spec, pm = self.spec, self.maps
        M, G, q = spec.steps, spec.robots, spec.derivative
        Yn = np.array(Y, dtype=float)
        Yn[:, :, 0] -= np.asarray(spec.origin)[:, None, :]
        Yn *= (spec.time_scale ** np.arange(q))[None, None, :, None]
        full = np.zeros((G, self.dim, M + 1, pm.stride))
        full[..., :q] = Yn.transpose(0, 3, 1, 2)
        full[:, :, :M, q:] = np.asarray(B, dtype=float).transpose(0, 3, 1, 2)
        return full.reshape(G, self.dim, -1)[:, :, :self.per_dim].reshape(-1)


def hermite_trajectory(Y: np.ndarray, B: np.ndarray, durations: np.ndarray, degree: int,
                       derivative: int) -> PiecewisePolynomial:
    """The piecewise polynomial with knot derivatives ``Y`` (M+1, q, dim) and bubbles ``B`` (M, nb, dim)."""
    pm = piece_maps(degree, derivative)
    T = np.asarray(durations, dtype=float)
    z = np.concatenate([Y[:-1], Y[1:], B], axis=1)  # (M, nz, dim), local order of PieceMaps
    c = pm.tau_coefficients(z, T)
    return PiecewisePolynomial(T, tau_to_time(c, T))
