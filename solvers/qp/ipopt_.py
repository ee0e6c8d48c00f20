"""Ipopt through CasADi's ``nlpsol``: the QP as an NLP, and general NLPs.

Wächter, Biegler, "On the implementation of an interior-point filter line-search
algorithm for large-scale nonlinear programming", Mathematical Programming 106 (2006);
called through CasADi (Andersson et al., Mathematical Programming Computation 11, 2019).

Two entry points share one translation of :class:`Options` (Ipopt's statuses are mapped
by :func:`solvers.nlp.ipopt_.status_of`, shared with the NLP backend called ``ipopt``,
which minimizes functions given by Python callables: the time refinement's):

- :class:`IpoptNLP` / :func:`solve_nlp` solve a general NLP given as CasADi expressions,

  .. math::

      \\min_x f(x, p) \\quad \\text{s.t.} \\quad lbg \\le g(x, p) \\le ubg,
      \\quad lbx \\le x \\le ubx,

  built once (``nlpsol``) and solved for any parameter value ``p`` and bounds; this is
  what nonlinear variants of the smoothing problem (e.g. time allocation) will use.
- :class:`IpoptQP` is the registry backend: the QP built once as an NLP whose
  parameters are the nonzeros of ``P`` and ``A`` and the vector ``q`` (SX expressions,
  so Ipopt gets the exact, constant Hessian and Jacobian), with ``l <= Ax <= u`` as
  ``lbg <= g <= ubg``. An update with the same sparsity pattern only changes ``p`` and
  the bounds.

Ipopt is an interior-point method: ``warm_start`` only sets the initial point ``x0``, and
the record says ``warm_start=False`` (such a start barely helps an interior-point method,
so :class:`~solvers.qp.QPSolver` does not pass one).
In QP mode we tell Ipopt that the Hessian and constraint Jacobian are constant
(``hessian_constant``, ``jac_c_constant``, ``jac_d_constant``), which saves their
re-evaluation. We do not use Ipopt's ``mehrotra_algorithm`` (suggested for convex QPs):
with it, the infeasible test problem ends in ``Diverging_Iterates`` instead of
``Infeasible_Problem_Detected``.

Tolerances: ``tol``, ``constr_viol_tol`` and ``compl_inf_tol`` are ``eps_abs``,
``dual_inf_tol`` is ``max(eps_abs, eps_rel)``; with the defaults (1e-8) the test problems
agree with their known optima to 1e-8 in the objective.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field

import numpy as np

from solvers.errors import InvalidProblem
from solvers.nlp.ipopt_ import status_of
from solvers.qp.base import PreparedQP
from solvers.qp.capabilities import QPCapabilities
from solvers.qp.problem import QPProblem
from solvers.qp.solution import Options, Status
from solvers.registry import Backend

log = logging.getLogger(__name__)


def _settings(o: Options, quadratic: bool) -> dict:
    """``Options`` as ``nlpsol('ipopt')`` options (the one place they are translated)."""
    # polish: nothing to polish after an interior-point solve; ignored.
    ipopt = {
        "tol": o.eps_abs,
        "constr_viol_tol": o.eps_abs,
        "dual_inf_tol": max(o.eps_abs, o.eps_rel),
        "compl_inf_tol": o.eps_abs,
        "max_iter": int(o.max_iter),
        "print_level": 5 if o.verbose else 0,
        "sb": "yes",  # no banner
    }
    if o.time_limit is not None:
        ipopt["max_wall_time"] = float(o.time_limit)
    if quadratic:
        ipopt.update(hessian_constant="yes", jac_c_constant="yes", jac_d_constant="yes")
    return {"ipopt": ipopt, "print_time": bool(o.verbose), "error_on_fail": False}


@dataclass(frozen=True)
class NLPResult:
    """What :meth:`IpoptNLP.solve` returns (no exception on failure: check ``status``).

    Attributes
    ----------
    x, f, g
        Final point, objective and constraint values.
    lam_x, lam_g
        Multipliers of the variable bounds and constraints, with the sign convention
        ``grad f + J_g' lam_g + lam_x = 0`` (positive at an active upper bound).
    status, raw_status
        Mapped and Ipopt's own status.
    iterations
        Ipopt iterations.
    solve_time_s
        Wall time of the solve.
    """

    x: np.ndarray
    f: float
    g: np.ndarray
    lam_x: np.ndarray
    lam_g: np.ndarray
    status: Status
    raw_status: str
    iterations: int
    solve_time_s: float
    stats: dict = field(default_factory=dict, repr=False)


class IpoptNLP:
    """An NLP built once as CasADi ``nlpsol('ipopt')``, solved for any parameter value.

    Parameters
    ----------
    x
        Decision variables, a CasADi ``SX`` or ``MX`` column symbol.
    f
        Scalar objective expression in ``x`` (and ``p``).
    g
        Constraint expressions (a column); ``None`` for none.
    p
        Parameter symbol the expressions depend on; ``None`` for none.
    options
        Tolerances, iteration cap, time limit, verbosity.
    quadratic
        Declare ``f`` quadratic and ``g`` linear in ``x`` (constant Hessian and Jacobian,
        evaluated once per solve). Only set it when true: Ipopt trusts it.
    """

    def __init__(self, x, f, g=None, p=None, options: Options | None = None, *, quadratic: bool = False) -> None:
        import casadi as ca

        self.options = options or Options()
        nlp = {"x": x, "f": f}
        if g is not None:
            nlp["g"] = ca.densify(g)  # a row without entries (a free row of a QP) leaves g sparse, which nlpsol refuses
        if p is not None:
            nlp["p"] = p
        self.n = int(x.numel())
        self.ng = 0 if g is None else int(g.numel())
        self.np = 0 if p is None else int(p.numel())
        self._solver = ca.nlpsol("mrfswarm_nlp", "ipopt", nlp, _settings(self.options, quadratic))

    def solve(
        self,
        x0: np.ndarray | None = None,
        p: np.ndarray | None = None,
        *,
        lbx: np.ndarray | float = -np.inf,
        ubx: np.ndarray | float = np.inf,
        lbg: np.ndarray | float = -np.inf,
        ubg: np.ndarray | float = np.inf,
    ) -> NLPResult:
        """Solve from ``x0`` (zeros if ``None``) for parameter value ``p``.

        Raises
        ------
        InvalidProblem
            If ``x0`` or ``p`` has the wrong size.
        """
        x0 = np.zeros(self.n) if x0 is None else np.asarray(x0, dtype=float).reshape(-1)
        if x0.size != self.n:
            raise InvalidProblem(f"x0 has {x0.size} entries, the NLP has {self.n} variables")
        args = dict(x0=x0, lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg)
        if self.np:
            if p is None or np.size(p) != self.np:
                raise InvalidProblem(f"the NLP needs a parameter value of size {self.np}, got {None if p is None else np.size(p)}")
            args["p"] = np.asarray(p, dtype=float).reshape(-1)
        t0 = time.perf_counter()
        r = self._solver(**args)
        dt = time.perf_counter() - t0
        stats = self._solver.stats()
        status, raw = status_of(stats)
        return NLPResult(
            x=np.asarray(r["x"]).reshape(-1),
            f=float(r["f"]),
            g=np.asarray(r["g"]).reshape(-1),
            lam_x=np.asarray(r["lam_x"]).reshape(-1),
            lam_g=np.asarray(r["lam_g"]).reshape(-1),
            status=status,
            raw_status=raw,
            iterations=int(stats.get("iter_count", 0)),
            solve_time_s=dt,
            stats=stats,
        )


def solve_nlp(
    x,
    f,
    g=None,
    p=None,
    *,
    x0: np.ndarray | None = None,
    p_value: np.ndarray | None = None,
    lbx: np.ndarray | float = -np.inf,
    ubx: np.ndarray | float = np.inf,
    lbg: np.ndarray | float = -np.inf,
    ubg: np.ndarray | float = np.inf,
    options: Options | None = None,
) -> NLPResult:
    """Solve ``min f(x, p) s.t. lbg <= g(x, p) <= ubg, lbx <= x <= ubx`` once with Ipopt.

    For repeated solves of one formulation build an :class:`IpoptNLP` once and call its
    ``solve``; this function builds and solves in one go.

    Parameters
    ----------
    x, f, g, p
        CasADi symbols/expressions as in :class:`IpoptNLP`.
    x0
        Initial point (zeros if ``None``).
    p_value
        Value of ``p``.
    lbx, ubx, lbg, ubg
        Bounds (scalars broadcast; ``+-inf`` for none; ``lbg == ubg`` for equalities).
    options
        Tolerances, iteration cap, time limit, verbosity.

    Returns
    -------
    NLPResult
        Check ``result.status.ok``; nothing is raised for a failed solve.

    Examples
    --------
    >>> import casadi as ca
    >>> x = ca.SX.sym("x", 2)
    >>> r = solve_nlp(x, (x[0] - 1) ** 2 + (x[1] - 2) ** 2, x[0] + x[1], lbg=0, ubg=1)
    >>> r.status.ok, np.round(r.x, 6).tolist()
    (True, [0.0, 1.0])
    """
    return IpoptNLP(x, f, g, p, options).solve(x0, p_value, lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg)


class IpoptQP(PreparedQP):
    """The QP as a parametric NLP in Ipopt, built once per sparsity pattern."""

    name = "ipopt"

    def _setup(self, problem: QPProblem) -> None:
        import casadi as ca

        P, A = problem.P, problem.A
        x = ca.SX.sym("x", problem.n)
        p_P = ca.SX.sym("P", P.nnz)
        p_q = ca.SX.sym("q", problem.n)
        p_A = ca.SX.sym("A", A.nnz)
        P_sym = ca.SX(ca.Sparsity(P.shape[0], P.shape[1], P.indptr.tolist(), P.indices.tolist()), p_P)
        A_sym = ca.SX(ca.Sparsity(A.shape[0], A.shape[1], A.indptr.tolist(), A.indices.tolist()), p_A)
        f = 0.5 * ca.bilin(P_sym, x, x) + ca.dot(p_q, x)
        g = ca.mtimes(A_sym, x) if problem.m else None
        self._nlp = IpoptNLP(x, f, g, ca.vertcat(p_P, p_q, p_A), self.options, quadratic=True)

    def update(self, problem: QPProblem) -> None:
        self._check_same_shape(problem)  # same pattern: the NLP is reused, only p changes
        self.problem = problem

    def _solve(self, warm_start):
        pr = self.problem
        p = np.concatenate([pr.P.data, pr.q, pr.A.data])
        bounds = dict(lbg=pr.l, ubg=pr.u) if pr.m else {}
        r = self._nlp.solve(warm_start, p, **bounds)
        return r.x, r.status, r.raw_status, r.iterations, (r.lam_g if pr.m else np.zeros(0))


BACKEND = Backend(
    name="ipopt",
    entry=IpoptQP,
    requires=("casadi",),
    extra="casadi",
    summary="Ipopt via CasADi nlpsol: interior point NLP solver (the QP as an NLP; general NLPs via solve_nlp); "
            "builds each QP anew: tens of times piqp's time in a run",
    capabilities=QPCapabilities(inequalities=True, warm_start=False, detects_infeasibility=True, sparse=True, nlp=True),
)
