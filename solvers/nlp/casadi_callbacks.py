"""An :class:`~solvers.nlp.problem.NLPProblem` as a CasADi ``nlpsol`` problem, for the CasADi backends.

The objective is a ``casadi.Callback`` whose Jacobian is another callback (the problem's
gradient), so CasADi's NLP solvers see ``f`` and ``grad f`` as functions of ``x``; the
linear rows are the expression ``A x``. Neither has a Hessian: the backends use
limited-memory quasi-Newton approximations. A deadline is a third callback, CasADi's
``iteration_callback``, which asks the solver to stop once the time is up (CasADi then
reports ``User_Requested_Stop``).

A point is clipped into the bounds before ``f`` or its gradient is evaluated, as SciPy does
for SLSQP: Ipopt relaxes the bounds by a relative 1e-8 (``bound_relax_factor``) and
sqpmethod's QP subproblems keep them to their tolerance, so both ask for points just
outside (by 1e-8 on the tests' bounded Rosenbrock), where ``f`` may not be defined.

Only the backends' ``solve`` calls these functions, so ``casadi`` is imported inside them.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from solvers.nlp.problem import NLPProblem

#: CasADi's status when the iteration callback asked to stop: only the deadline asks.
USER_STOP = "User_Requested_Stop"


@dataclass
class CasadiNLP:
    """The problem in CasADi's terms; keeps the callbacks alive as long as the solver.

    Attributes
    ----------
    nlp
        ``{"x": x, "f": f(x)[, "g": A x]}`` for ``nlpsol``.
    bounds
        ``lbx``, ``ubx`` (and ``lbg``, ``ubg``) for the call.
    keep
        The callback objects (CasADi holds them by raw pointer).
    """

    nlp: dict
    bounds: dict
    keep: list


def casadi_nlp(problem: NLPProblem) -> CasadiNLP:
    """The problem as an ``nlpsol`` dictionary of symbolic expressions and its bounds."""
    import casadi as ca

    n = problem.n

    def _inside(x) -> np.ndarray:
        return np.clip(np.asarray(x, dtype=float).reshape(-1), problem.lower, problem.upper)

    failed: list[Exception] = []  # a callable raised: CasADi printed its traceback (and its own lines) per raise

    def _quiet(call, x, shape):
        """``call(x)``, or NaN of ``shape`` once a call raised: the exception is the dispatch's to raise after the
        solve (it recorded it), and CasADi sees a point without a value instead of a Python error to print."""
        if failed:
            return np.full(shape, np.nan)
        try:
            return np.asarray(call(x), dtype=float).reshape(shape)
        except Exception as e:
            failed.append(e)
            return np.full(shape, np.nan)

    class _Gradient(ca.Callback):
        def __init__(self, name: str) -> None:
            ca.Callback.__init__(self)
            self.construct(name, {})

        def get_n_in(self) -> int:
            return 2  # x and the (unused) value of f

        def get_n_out(self) -> int:
            return 1

        def get_sparsity_in(self, i: int):
            return ca.Sparsity.dense(n, 1) if i == 0 else ca.Sparsity.dense(1, 1)

        def get_sparsity_out(self, i: int):
            return ca.Sparsity.dense(1, n)

        def eval(self, arg):
            return [_quiet(problem.grad, _inside(arg[0]), (1, n))]

    class _Objective(ca.Callback):
        def __init__(self, name: str) -> None:
            ca.Callback.__init__(self)
            self.construct(name, {})

        def get_n_in(self) -> int:
            return 1

        def get_n_out(self) -> int:
            return 1

        def get_sparsity_in(self, i: int):
            return ca.Sparsity.dense(n, 1)

        def get_sparsity_out(self, i: int):
            return ca.Sparsity.dense(1, 1)

        def eval(self, arg):
            return [_quiet(problem.fun, _inside(arg[0]), (1, 1))]

        def has_jacobian(self) -> bool:
            return True

        def get_jacobian(self, name, inames, onames, opts):
            self._jac = _Gradient(name)  # kept alive as long as the objective
            return self._jac

    f = _Objective("objective")
    x = ca.MX.sym("x", n)
    nlp: dict[str, Any] = {"x": x, "f": f(x)}
    bounds = {"x0": problem.x0, "lbx": problem.lower, "ubx": problem.upper}
    if problem.m:
        nlp["g"] = ca.mtimes(ca.DM(problem.rows), x)
        bounds.update(lbg=problem.lb, ubg=problem.ub)
    return CasadiNLP(nlp=nlp, bounds=bounds, keep=[f])


def deadline_callback(problem: NLPProblem, seconds: float):
    """A CasADi ``iteration_callback`` that asks the solver to stop ``seconds`` after its ``start()``.

    Call ``start()`` just before calling the solver; without it the clock starts at the
    first iteration.
    """
    import casadi as ca

    n, m = problem.n, problem.m

    class _Deadline(ca.Callback):
        def __init__(self) -> None:
            ca.Callback.__init__(self)
            self.deadline: float | None = None
            self.construct("deadline", {})

        def get_n_in(self) -> int:
            return ca.nlpsol_n_out()

        def get_n_out(self) -> int:
            return 1

        def get_name_in(self, i: int) -> str:
            return ca.nlpsol_out(i)

        def get_name_out(self, i: int) -> str:
            return "stop"

        def get_sparsity_in(self, i: int):
            name = ca.nlpsol_out(i)
            if name == "f":
                return ca.Sparsity.scalar()
            if name in ("x", "lam_x"):
                return ca.Sparsity.dense(n)
            if name in ("g", "lam_g"):
                return ca.Sparsity.dense(m)
            return ca.Sparsity(0, 0)

        def start(self) -> None:
            self.deadline = time.perf_counter() + seconds

        def eval(self, arg):
            if self.deadline is None:
                self.start()
            return [1 if time.perf_counter() >= self.deadline else 0]

    return _Deadline()
