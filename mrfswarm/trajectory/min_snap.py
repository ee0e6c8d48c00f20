"""Solve min-snap problems with the closed form or any QP backend of :mod:`solvers.qp`.

>>> from mrfswarm.trajectory import solve_min_snap
>>> res = solve_min_snap([[0, 0], [1, 0], [1, 1]], [1.0, 1.0])          # doctest: +SKIP
>>> res.trajectory(0.5), res.cost, res.backend                         # doctest: +SKIP

Two routes solve a problem, named by :attr:`MinSnapResult.method`: the *banded* route
(:data:`BANDED`, the closed form of :mod:`mrfswarm.trajectory.banded`, linear in the
number of pieces; the accuracy reference) and the *QP* route (:data:`QP_ROUTE`, the
formulated QP handed to a backend of ``solvers.qp.BACKENDS``). A backend is chosen by its
registry name; choosing the registry's equality-only backend ``closed_form``
(:data:`CLOSED_FORM`) takes the banded route when it applies (no corridor, degree
``2q - 1``), and the QP route with that backend otherwise; with a corridor it is an error,
since corridor inequalities need a QP backend. ``None`` chooses ``closed_form`` without a
corridor and ``solvers.qp.DEFAULT_BACKEND`` with one. The result's ``backend`` is the
backend chosen (``closed_form`` on the banded route too).

The QP path evaluates the formulation compiled once per shape
(:mod:`mrfswarm.trajectory.formulation`) on normalized data (see :class:`Normalization`)
and maps the solution back; :class:`MinSnapSolver` keeps a :class:`solvers.qp.QPSolver`
per backend, so that a re-solve of the same shape only updates the data and warm-starts.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

import solvers.qp
from mrfswarm.trajectory import banded
from mrfswarm.trajectory.corridor import Corridor
from mrfswarm.trajectory.formulation import compiled_min_snap
from mrfswarm.trajectory.polynomial import PiecewisePolynomial, piece_costs, tau_to_time
from mrfswarm.trajectory.problem import DEFAULT_DEGREE, DEFAULT_DERIVATIVE, EndSpec, MinSnapProblem, MinSnapShape
from solvers.errors import InvalidProblem, SolverNotFound
from solvers.qp import Options, QPProblem, QPSolver, Solution

log = logging.getLogger(__name__)

#: The registry name of the equality-only QP backend (solvers/qp/closed_form.py).
CLOSED_FORM = "closed_form"
#: The two routes, as :attr:`MinSnapResult.method` names them.
BANDED = "banded"
QP_ROUTE = "qp"


@dataclass(frozen=True)
class Normalization:
    """The exact change of units under which the QP is solved.

    Positions :math:`p = \\text{center} + \\text{scale}\\, \\tilde p`, durations
    :math:`T = \\text{time\\_scale}\\, \\tilde T`. The optimum maps onto itself (the
    problem is equivariant under both), a given r-th derivative becomes
    :math:`g\\, \\text{time\\_scale}^r / \\text{scale}`, and the cost
    :math:`J = \\text{scale}^2\\, \\text{time\\_scale}^{1-2q} \\tilde J`.
    """

    center: np.ndarray
    scale: float
    time_scale: float

    @classmethod
    def of(cls, problem: MinSnapProblem) -> Normalization:
        """Centre and half-extent of the waypoints, geometric mean of the durations."""
        lo, hi = problem.waypoints.min(axis=0), problem.waypoints.max(axis=0)
        half = float(np.max(hi - lo)) / 2
        return cls(center=(lo + hi) / 2, scale=half if half > 0 else 1.0,
                   time_scale=float(np.exp(np.mean(np.log(problem.durations)))))

    def arguments(self, problem: MinSnapProblem) -> tuple:
        """The normalized data of ``problem``, as the compiled formulation takes it."""
        s = problem.shape
        c, L, Ts = self.center, self.scale, self.time_scale
        lo = hi = None
        if problem.corridor is not None:
            lo = (problem.corridor.lower - c) / L
            hi = (problem.corridor.upper - c) / L
        g0 = problem.start * (Ts ** np.arange(1, s.start_order + 1))[:, None] / L
        g1 = problem.end * (Ts ** np.arange(1, s.end_order + 1))[:, None] / L
        tol = None if problem.waypoint_tolerance is None else problem.waypoint_tolerance / L
        return (problem.waypoints - c) / L, problem.durations / Ts, lo, hi, g0, g1, tol

    def qp(self, problem: MinSnapProblem) -> QPProblem:
        """The normalized standard-form QP of ``problem`` (compiled formulation evaluated)."""
        return compiled_min_snap(problem.shape).evaluate(*self.arguments(problem))

    def tau_coefficients(self, problem: MinSnapProblem, x: np.ndarray) -> np.ndarray:
        """(M, D+1, dim) physical tau-coefficients from a normalized QP solution ``x``."""
        cn = compiled_min_snap(problem.shape).coefficients(x, problem.durations / self.time_scale) * self.scale
        cn[:, 0, :] += self.center
        return cn


def min_snap_qp(problem: MinSnapProblem) -> tuple[QPProblem, Normalization]:
    """The formulated standard-form QP of ``problem`` and the normalization it uses.

    The QP's variables are normalized knot derivatives and bubble coefficients (see
    :mod:`mrfswarm.trajectory.formulation`); map a solution back with
    :meth:`Normalization.tau_coefficients`.
    """
    norm = Normalization.of(problem)
    return norm.qp(problem), norm


@dataclass(frozen=True)
class MinSnapResult:
    """A solved smoothing problem.

    Attributes
    ----------
    trajectory
        The piecewise polynomial (coefficients in local time).
    cost
        :math:`\\int \\|\\sigma^{(q)}\\|^2 dt`, exact, in physical units.
    backend
        ``"closed_form"`` or the QP backend's registry name.
    method
        The route: :data:`BANDED` (``"banded"``, the closed form) or :data:`QP_ROUTE`
        (``"qp"``, the formulated QP).
    formulate_time_s, setup_time_s, solve_time_s
        Evaluating the compiled formulation (and normalizing), backend setup (0 for the
        banded path, or a cheap update on a warm re-solve), and solving.
    solution
        The backend's :class:`~solvers.qp.Solution` on the QP path, else ``None``.
    """

    trajectory: PiecewisePolynomial
    cost: float
    backend: str
    method: str
    formulate_time_s: float
    setup_time_s: float
    solve_time_s: float
    solution: Solution | None = None

    @property
    def total_time_s(self) -> float:
        """Formulation, setup and solve together."""
        return self.formulate_time_s + self.setup_time_s + self.solve_time_s


class MinSnapSolver:
    """Solves min-snap problems with one backend, reusing its setup across same-shape solves.

    Parameters
    ----------
    backend
        A name of ``solvers.qp.BACKENDS`` or ``None``; ``"closed_form"`` takes the banded
        route where it applies (see the module docstring).
    options
        QP options (tolerances, iterations, time limit).
    warm
        Reuse the prepared backend (update + warm start) when the next problem has the
        same shape.
    formulated
        Always take the QP route, never the banded one; ``"closed_form"`` then is only
        the registry's equality-only backend (for tests and benchmarks of the QP route).
    """

    def __init__(self, backend: str | None = None, options: Options | None = None, *, warm: bool = True,
                 formulated: bool = False) -> None:
        if backend is not None and (backend != CLOSED_FORM or formulated):
            solvers.qp.BACKENDS.get(backend)  # fail early on an unknown or missing backend
        self.backend = backend
        self.options = options
        self.warm = warm
        self.formulated = formulated
        self._solvers: dict[str, QPSolver] = {}  # one reusable handle per backend the route picks

    def _route(self, problem: MinSnapProblem) -> tuple[str, str]:
        """``(backend, route)`` for ``problem``: the backend chosen and :data:`BANDED` or :data:`QP_ROUTE`."""
        name = self.backend
        if name is None:
            name = solvers.qp.DEFAULT_BACKEND if problem.has_corridor else CLOSED_FORM
        if name == CLOSED_FORM:
            if problem.has_corridor or problem.waypoint_tolerance is not None:
                raise InvalidProblem(
                    "corridor constraints and waypoint tolerances need a QP backend (installed: "
                    f"{', '.join(b for b in solvers.qp.available() if b != CLOSED_FORM) or 'none'}); "
                    "closed_form solves equality-only problems"
                )
            if banded.supports(problem) and not self.formulated:
                return CLOSED_FORM, BANDED
            if CLOSED_FORM not in solvers.qp.BACKENDS:
                raise SolverNotFound(
                    f"degree {problem.degree} > 2q - 1 = {2 * problem.derivative - 1} needs the generic "
                    f"closed_form QP backend, which is not registered; installed: {', '.join(solvers.qp.available())}"
                )
        return name, QP_ROUTE

    def solve(self, problem: MinSnapProblem) -> MinSnapResult:
        """Solve ``problem``.

        Raises
        ------
        InvalidProblem
            ``closed_form`` asked for a problem with a corridor, or a malformed problem.
        SolverNotFound
            Unknown or missing backend.
        InfeasibleError
            The corridor leaves no feasible trajectory (backend's verdict).
        SolverError
            Any other backend failure.
        """
        name, route = self._route(problem)
        T, q = problem.durations, problem.derivative
        if route == BANDED:
            t0 = time.perf_counter()
            sol = banded.solve_banded(problem)
            dt = time.perf_counter() - t0
            traj = PiecewisePolynomial(T, tau_to_time(sol.coefficients, T))
            return MinSnapResult(traj, sol.cost, CLOSED_FORM, BANDED, 0.0, 0.0, dt)
        t0 = time.perf_counter()
        qp, norm = min_snap_qp(problem)
        t_form = time.perf_counter() - t0
        solver = self._solvers.get(name)
        if solver is None:
            solver = self._solvers[name] = QPSolver(name, self.options, reuse=self.warm)
        qp_sol = solver.solve(qp)
        c_tau = norm.tau_coefficients(problem, qp_sol.x)
        traj = PiecewisePolynomial(T, tau_to_time(c_tau, T))
        log.debug("min-snap %s via %s: %d iterations, status %s", problem.shape, name, qp_sol.iterations,
                  qp_sol.status)
        return MinSnapResult(traj, float(piece_costs(c_tau, T, q).sum()), name, QP_ROUTE, t_form, qp_sol.setup_time_s,
                             qp_sol.solve_time_s, qp_sol)


class MinSnapBatchSolver:
    """Solves many problems of one shape as a single block-diagonal QP.

    The receding horizon smooths every robot of a window with the same shape (pieces,
    samples, end conditions; only data differ), and the robots' problems are
    independent, so stacking them costs one backend setup and solve per window instead
    of one per robot. Each block is normalized on its own (see :class:`Normalization`),
    so the blocks' optima are exactly those of the separate problems. The stacked
    pattern is built once per (shape, number of problems); with ``warm`` the prepared
    backend is updated and warm-started across calls of the same size.

    Parameters
    ----------
    backend
        A QP backend name (never the banded route: batches carry corridors).
    options
        QP options.
    warm
        Reuse the prepared backend across same-size batches.
    """

    def __init__(self, backend: str | None = None, options: Options | None = None, *, warm: bool = True) -> None:
        self.backend = backend or solvers.qp.DEFAULT_BACKEND
        solvers.qp.BACKENDS.get(self.backend)  # fail early on an unknown or missing backend
        self.options = options
        self.warm = warm
        self._patterns: dict = {}
        self._solvers: dict[tuple[MinSnapShape, int], QPSolver] = {}  # one reusable handle per batch size

    def _pattern(self, shape: MinSnapShape, N: int):
        key = (shape, N)
        if key not in self._patterns:
            comp = compiled_min_snap(shape)
            (pr, pc), (ar, ac) = comp.patterns

            def stack(rows: np.ndarray, colptr: np.ndarray, n_rows: int) -> tuple[np.ndarray, np.ndarray]:
                nnz = colptr[-1]
                r = (rows[None, :] + n_rows * np.arange(N)[:, None]).ravel()
                c = np.concatenate([(colptr[:-1][None, :] + nnz * np.arange(N)[:, None]).ravel(), [N * nnz]])
                return r.astype(np.int32), c.astype(np.int32)

            self._patterns[key] = (stack(pr, pc, comp.n), stack(ar, ac, comp.m))
        return self._patterns[key]

    def solve(self, problems: list[MinSnapProblem]) -> list[PiecewisePolynomial]:
        """The optimal trajectory of each problem (all of one shape).

        Raises
        ------
        InvalidProblem
            Problems of different shapes.
        InfeasibleError, SolverError
            As :meth:`MinSnapSolver.solve` (for the batch as a whole).
        """
        shape = problems[0].shape
        if any(p.shape != shape for p in problems):
            raise InvalidProblem("a batch must hold problems of one shape")
        N = len(problems)
        comp = compiled_min_snap(shape)
        nP, nA = (int(comp.patterns[0][1][-1]), int(comp.patterns[1][1][-1]))
        n, m = comp.n, comp.m
        Pd, Ad, lo, up = np.empty(N * nP), np.empty(N * nA), np.empty(N * m), np.empty(N * m)
        norms = [Normalization.of(p) for p in problems]
        for k, (p, norm) in enumerate(zip(problems, norms)):
            comp.evaluate_into([Pd[k * nP:(k + 1) * nP], Ad[k * nA:(k + 1) * nA], lo[k * m:(k + 1) * m],
                                up[k * m:(k + 1) * m]], *norm.arguments(p))
        (pr, pc), (ar, ac) = self._pattern(shape, N)
        qp = QPProblem(P=sp.csc_matrix((Pd, pr, pc), shape=(N * n, N * n)), q=np.zeros(N * n),
                       A=sp.csc_matrix((Ad, ar, ac), shape=(N * m, N * n)), l=lo, u=up)
        solver = self._solvers.get((shape, N))
        if solver is None:
            solver = self._solvers[(shape, N)] = QPSolver(self.backend, self.options, reuse=self.warm)
        sol = solver.solve(qp)
        X = sol.x.reshape(N, n)
        return [PiecewisePolynomial(p.durations, tau_to_time(norm.tau_coefficients(p, X[k]), p.durations))
                for k, (p, norm) in enumerate(zip(problems, norms))]


def solve_min_snap(
    waypoints: np.ndarray,
    durations: np.ndarray,
    *,
    degree: int = DEFAULT_DEGREE,
    derivative: int = DEFAULT_DERIVATIVE,
    continuity: int | None = None,
    start: EndSpec = "rest",
    end: EndSpec = "rest",
    corridor: Corridor | None = None,
    backend: str | None = None,
    options: Options | None = None,
) -> MinSnapResult:
    """Smooth ``waypoints`` into the minimum-``derivative`` piecewise polynomial.

    Parameters
    ----------
    waypoints
        (M+1, dim) positions the trajectory passes through at its knots.
    durations
        (M,) positive piece durations (seconds); see
        :mod:`mrfswarm.trajectory.time_allocation` to compute them.
    degree, derivative, continuity, start, end, corridor
        See :class:`~mrfswarm.trajectory.problem.MinSnapProblem`.
    backend
        ``"closed_form"``, a name of ``solvers.qp.BACKENDS`` or ``None`` (automatic).
    options
        QP backend options.

    Returns
    -------
    MinSnapResult

    Raises
    ------
    InvalidProblem, SolverNotFound, InfeasibleError, SolverError
        See :meth:`MinSnapSolver.solve`.
    """
    problem = MinSnapProblem(waypoints, durations, degree=degree, derivative=derivative, continuity=continuity,
                             start=start, end=end, corridor=corridor)
    return MinSnapSolver(backend, options, warm=False).solve(problem)
