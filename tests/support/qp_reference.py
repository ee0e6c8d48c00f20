"""QPs with known optima, derived analytically or constructed from a chosen KKT point.

Each builder returns a :class:`Reference`: the problem, its unique optimum ``x`` (and the
multipliers ``y`` where they are unique), and whether it has inequality rows. No QP
backend is used to make a reference.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from solvers.qp import QPProblem


@dataclass(frozen=True)
class Reference:
    name: str
    problem: QPProblem
    x: np.ndarray
    y: np.ndarray | None = None

    @property
    def objective(self) -> float:
        return self.problem.objective(self.x)

    @property
    def has_inequalities(self) -> bool:
        return self.problem.has_inequalities


def box_projection(seed: int = 0, n: int = 12) -> Reference:
    """Weighted projection of a point onto a box: ``min sum_i w_i (x_i - c_i)^2 / 2``,
    ``lo <= x <= hi`` (some sides infinite). The optimum is ``clip(c, lo, hi)``, whatever
    the positive weights, since the problem separates per coordinate.

    One extra row ``-inf <= sum(x) <= inf`` is free and must be ignored.
    """
    rng = np.random.default_rng(seed)
    w = rng.uniform(0.5, 3.0, n)
    c = rng.uniform(-3, 3, n)
    lo = rng.uniform(-2, 0, n)
    hi = rng.uniform(0, 2, n)
    lo[::4] = -np.inf
    hi[1::4] = np.inf
    A = sp.vstack([sp.eye(n), sp.csr_matrix(np.ones((1, n)))])
    problem = QPProblem(P=sp.diags(w), q=-w * c, A=A, l=np.r_[lo, -np.inf], u=np.r_[hi, np.inf])
    x = np.clip(c, lo, hi)
    # multipliers: w (x - c) + y = 0 on the box rows, 0 on the free row
    y = np.r_[-(w * (x - c)), 0.0]
    return Reference("box_projection", problem, x, y)


def least_norm(seed: int = 1, m: int = 5, n: int = 12) -> Reference:
    """``min ||x||^2 / 2`` s.t. ``A x = b`` with ``A`` of full row rank: ``x = pinv(A) b``
    and ``y = -(A A')^{-1} b``."""
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((m, n))
    A[np.abs(A) < 0.5] = 0.0  # some sparsity
    b = rng.standard_normal(m)
    x = np.linalg.pinv(A) @ b
    y = -np.linalg.solve(A @ A.T, b)
    problem = QPProblem(P=sp.eye(n), q=np.zeros(n), A=sp.csc_matrix(A), l=b, u=b)
    return Reference("least_norm", problem, x, y)


def nocedal_wright_16_4() -> Reference:
    """Nocedal & Wright, Numerical Optimization, Example 16.4:

    ``min (x1 - 1)^2 + (x2 - 2.5)^2`` s.t. ``x1 - 2 x2 + 2 >= 0``, ``-x1 - 2 x2 + 6 >= 0``,
    ``-x1 + 2 x2 + 2 >= 0``, ``x >= 0``.

    By hand: at ``x* = (1.4, 1.7)`` the first constraint is active (1.4 - 3.4 + 2 = 0), the
    others are slack (1.2, 4, 1.4, 1.7 > 0), and ``grad f = 2 (x* - (1, 2.5)) = (0.8, -1.6)
    = 0.8 (1, -2)`` = 0.8 times the active constraint's gradient, with multiplier 0.8 >= 0:
    the KKT conditions hold and the objective is strictly convex, so ``x*`` is the unique
    optimum. In standard form (``f = x'x - 2 x1 - 5 x2`` + const, row 0 as
    ``-2 <= x1 - 2 x2``) the active lower side carries ``y_0 = -0.8``.
    """
    P = 2.0 * sp.eye(2)
    q = np.array([-2.0, -5.0])
    A = np.array([[1.0, -2.0], [-1.0, -2.0], [-1.0, 2.0], [1.0, 0.0], [0.0, 1.0]])
    l = np.array([-2.0, -6.0, -2.0, 0.0, 0.0])
    u = np.full(5, np.inf)
    x = np.array([1.4, 1.7])
    y = np.array([-0.8, 0.0, 0.0, 0.0, 0.0])
    return Reference("nocedal_wright_16_4", QPProblem(P=P, q=q, A=sp.csc_matrix(A), l=l, u=u), x, y)


def random_equality(seed: int = 2, n: int = 30, m: int = 10, psd_rank: int | None = None) -> Reference:
    """Random sparse convex QP with equality rows only (and one free row); the reference
    is the dense numpy solve of its KKT system.

    With ``psd_rank`` the cost is only positive semidefinite (rank ``psd_rank``), as in
    min-snap, yet positive definite on the nullspace of ``A`` when ``psd_rank + m >= n``.
    """
    rng = np.random.default_rng(seed)
    k = psd_rank if psd_rank is not None else n
    B = sp.random(n, k, density=0.3, random_state=rng).toarray() + np.eye(n, k)
    P = B @ B.T + (0.0 if psd_rank is not None else 0.1) * np.eye(n)
    q = rng.standard_normal(n)
    A = sp.random(m, n, density=0.3, random_state=rng).toarray() + np.eye(m, n)
    b = rng.standard_normal(m)
    K = np.block([[P, A.T], [A, np.zeros((m, m))]])
    z = np.linalg.solve(K, np.r_[-q, b])
    A_all = np.vstack([A, rng.standard_normal((1, n))])
    problem = QPProblem(P=sp.csc_matrix(P), q=q, A=sp.csc_matrix(A_all), l=np.r_[b, -np.inf], u=np.r_[b, np.inf])
    name = "random_equality" if psd_rank is None else "random_equality_psd"
    return Reference(name, problem, z[:n], np.r_[z[n:], 0.0])


def random_inequality(seed: int = 3, n: int = 40, m: int = 60, n_eq: int = 5) -> Reference:
    """Random sparse strictly convex QP with equalities, one- and two-sided inequalities,
    built from a chosen KKT point.

    Pick ``x*``, a sparse ``A``, and per row a role: equality, active lower, active upper,
    or inactive; pick multipliers of the right sign (any sign on equalities, < 0 on active
    lower sides, > 0 on active upper sides, 0 on inactive rows); put the active sides at
    ``A x*`` and the inactive ones strictly away from it; set ``q = -P x* - A' y*``. Then
    ``(x*, y*)`` satisfies the KKT conditions with strict complementarity, so with ``P``
    positive definite ``x*`` is the unique optimum and ``y*`` the unique multipliers
    whenever the active rows are linearly independent (a random ``A`` with fewer active
    rows than variables).
    """
    rng = np.random.default_rng(seed)
    M = sp.random(n, n, density=0.1, random_state=rng)
    P = (M @ M.T + 0.5 * sp.eye(n)).tocsc()
    A = (sp.random(m, n, density=0.15, random_state=rng) + sp.eye(m, n)).tocsc()
    x = rng.standard_normal(n)
    ax = A @ x
    role = rng.choice(["lower", "upper", "inactive"], size=m, p=[0.2, 0.2, 0.6])
    role[:n_eq] = "eq"
    y = np.zeros(m)
    l = ax - rng.uniform(0.2, 1.0, m)
    u = ax + rng.uniform(0.2, 1.0, m)
    y[role == "eq"] = rng.standard_normal(np.sum(role == "eq"))
    lo_act, up_act = role == "lower", role == "upper"
    y[lo_act] = -rng.uniform(0.5, 2.0, lo_act.sum())
    y[up_act] = rng.uniform(0.5, 2.0, up_act.sum())
    l[lo_act | (role == "eq")] = ax[lo_act | (role == "eq")]
    u[up_act | (role == "eq")] = ax[up_act | (role == "eq")]
    one_sided = rng.random(m) < 0.3  # open the far side of some rows
    l[one_sided & (role == "upper")] = -np.inf
    u[one_sided & (role == "lower")] = np.inf
    u[one_sided & (role == "inactive")] = np.inf
    q = -(P @ x) - A.T @ y
    return Reference("random_inequality", QPProblem(P=P, q=q, A=A, l=l, u=u), x, y)


def unconstrained(seed: int = 6, n: int = 8) -> Reference:
    """No constraint rows at all (``m = 0``): ``x = -P^{-1} q``."""
    rng = np.random.default_rng(seed)
    B = rng.standard_normal((n, n))
    P = B @ B.T + np.eye(n)
    q = rng.standard_normal(n)
    problem = QPProblem(P=sp.csc_matrix(P), q=q, A=sp.csc_matrix((0, n)), l=np.zeros(0), u=np.zeros(0))
    return Reference("unconstrained", problem, np.linalg.solve(P, -q), np.zeros(0))


def infeasible() -> QPProblem:
    """``x1 + x2 = 1`` with ``x1 >= 1`` and ``x2 >= 1``: no feasible point."""
    A = sp.csc_matrix(np.array([[1.0, 1.0], [1.0, 0.0], [0.0, 1.0]]))
    return QPProblem(P=sp.eye(2), q=np.zeros(2), A=A, l=np.array([1.0, 1.0, 1.0]), u=np.array([1.0, np.inf, np.inf]))


# ---- a min-snap chain: the block-banded equality QP the smoothing stage produces ----

def _snap_cost(T: float, degree: int = 7) -> np.ndarray:
    """``Q`` with ``c'Qc = int_0^T (p''''(t))^2 dt`` for ``p(t) = sum_i c_i t^i``."""
    k = 4
    Q = np.zeros((degree + 1, degree + 1))
    for i in range(k, degree + 1):
        for j in range(k, degree + 1):
            ci = math.factorial(i) / math.factorial(i - k)
            cj = math.factorial(j) / math.factorial(j - k)
            e = i + j - 2 * k + 1
            Q[i, j] = ci * cj * T**e / e
    return Q


def _deriv_row(t: float, d: int, degree: int = 7) -> np.ndarray:
    """Row ``r`` with ``r @ c = p^(d)(t)``."""
    r = np.zeros(degree + 1)
    for i in range(d, degree + 1):
        r[i] = math.factorial(i) / math.factorial(i - d) * t ** (i - d)
    return r


def min_snap_chain(n_pieces: int, seed: int = 4, degree: int = 7) -> tuple[QPProblem, np.ndarray, np.ndarray]:
    """1-D min-snap through ``n_pieces + 1`` waypoints, at rest at both ends.

    Variables: the ``degree + 1`` coefficients of each piece (local time). Cost: the snap
    integral (the cost matrix doubled, as the standard form halves it). Equalities: each
    piece starts and ends at its waypoints, velocity, acceleration and jerk are continuous
    at interior knots, and velocity, acceleration, jerk vanish at both ends. The KKT
    matrix is block banded. Returns the problem, the durations and the waypoints.
    """
    rng = np.random.default_rng(seed)
    durations = rng.uniform(0.5, 1.5, n_pieces)
    waypoints = np.cumsum(rng.uniform(-1.0, 1.0, n_pieces + 1))
    nc = degree + 1
    n = nc * n_pieces
    P = sp.block_diag([2.0 * _snap_cost(T, degree) for T in durations], format="csc")
    rows, cols, vals, rhs = [], [], [], []

    def add(entries: list[tuple[int, np.ndarray]], value: float) -> None:
        r = len(rhs)
        for piece, coeffs in entries:
            nz = np.flatnonzero(coeffs)
            rows.extend([r] * nz.size)
            cols.extend(piece * nc + nz)
            vals.extend(coeffs[nz])
        rhs.append(value)

    for k, T in enumerate(durations):
        add([(k, _deriv_row(0.0, 0, degree))], waypoints[k])
        add([(k, _deriv_row(T, 0, degree))], waypoints[k + 1])
    for k in range(n_pieces - 1):
        for d in (1, 2, 3):
            add([(k, _deriv_row(durations[k], d, degree)), (k + 1, -_deriv_row(0.0, d, degree))], 0.0)
    for d in (1, 2, 3):
        add([(0, _deriv_row(0.0, d, degree))], 0.0)
        add([(n_pieces - 1, _deriv_row(durations[-1], d, degree))], 0.0)
    A = sp.csc_matrix((vals, (rows, cols)), shape=(len(rhs), n))
    b = np.array(rhs)
    return QPProblem(P=P, q=np.zeros(n), A=A, l=b, u=b), durations, waypoints


def derivative_jumps(x: np.ndarray, durations: np.ndarray, d: int, degree: int = 7) -> np.ndarray:
    """Jumps of the ``d``-th derivative at the interior knots of a min-snap chain ``x``."""
    C = x.reshape(len(durations), degree + 1)
    end = np.array([_deriv_row(T, d, degree) @ c for T, c in zip(durations, C)])
    start = np.array([_deriv_row(0.0, d, degree) @ c for c in C])
    return end[:-1] - start[1:]


def all_references() -> list[Reference]:
    """Every reference problem with a known optimum."""
    return [
        unconstrained(),
        box_projection(),
        least_norm(),
        nocedal_wright_16_4(),
        random_equality(),
        random_equality(seed=5, n=24, m=8, psd_rank=18),
        random_inequality(),
        min_snap_reference(),
    ]


def min_snap_reference(n_pieces: int = 10) -> Reference:
    """A short min-snap chain with its optimum from a dense numpy solve of the KKT system."""
    problem, _, _ = min_snap_chain(n_pieces)
    P, A, b = problem.P.toarray(), problem.A.toarray(), problem.l
    n, m = problem.n, problem.m
    z = np.linalg.solve(np.block([[P, A.T], [A, np.zeros((m, m))]]), np.r_[-problem.q, b])
    return Reference(f"min_snap_{n_pieces}", problem, z[:n], z[n:])
