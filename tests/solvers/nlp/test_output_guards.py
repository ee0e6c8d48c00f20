"""An NLP backend's answer is checked before it is trusted: an Outcome whose status is a Status and whose x has one
entry per variable (a backend returning the scalar 0.5 was reported OPTIMAL at x = (0.5, 0.5) on Rosenbrock; one
returning the status as a string ended in an AttributeError)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import solvers.nlp
import solvers.nlp.dispatch as dispatch
from solvers.errors import InvalidProblem, SolverError
from solvers.nlp import NLPProblem
from solvers.nlp.solution import Outcome
from solvers.status import Status


def rosenbrock() -> NLPProblem:
    def f(x):
        return float((1 - x[0]) ** 2 + 100 * (x[1] - x[0] ** 2) ** 2)

    def g(x):
        return np.array([-2 * (1 - x[0]) - 400 * x[0] * (x[1] - x[0] ** 2), 200 * (x[1] - x[0] ** 2)])

    return NLPProblem(f, g, np.array([-1.2, 1.0]), np.full(2, -5.0), np.full(2, 5.0))


def with_entry(monkeypatch, entry, like: str = "lbfgsb") -> str:
    record = dataclasses.replace(dispatch.BACKENDS.get(like), name="answers", entry=entry)
    real = dispatch.BACKENDS.get
    monkeypatch.setattr(dispatch.BACKENDS, "get", lambda name: record if name == "answers" else real(name))
    return "answers"


@pytest.mark.parametrize("outcome, match", [
    (Outcome(np.array(0.5), Status.OPTIMAL, "done", 1), "returned x of 1 entries for 2 variables"),
    (Outcome(np.ones(3), Status.OPTIMAL, "done", 1), "returned x of 3 entries for 2 variables"),
    (Outcome(np.ones(2), "optimal", "done", 1), "returned the status 'optimal', not a solvers.nlp.Status"),
    ((np.ones(2), Status.OPTIMAL), "returned tuple, not a solvers.nlp Outcome"),
])
def test_what_is_not_an_outcome_is_a_solver_error(monkeypatch, outcome, match):
    name = with_entry(monkeypatch, lambda problem, options: outcome)
    with pytest.raises(SolverError, match=match):
        solvers.nlp.minimize(rosenbrock(), name)


def test_a_well_formed_outcome_is_completed(monkeypatch):
    name = with_entry(monkeypatch, lambda problem, options: Outcome(np.ones(2), Status.OPTIMAL, "done", 7))
    sol = solvers.nlp.minimize(rosenbrock(), name)
    assert sol.status is Status.OPTIMAL and np.allclose(sol.x, 1.0) and sol.objective == 0.0 and sol.iterations == 7


def test_a_point_that_is_not_finite_is_never_handed_to_f(monkeypatch):
    """A backend answering NaN "optimal": dispatch evaluated the user's f there to complete the solution, and a time
    refinement's f (a window QP at those durations) raised "P, q and A must be finite", naming no backend (a tour's
    plugin). The caller gets the best point the run evaluated, not reported optimal."""
    seen = []

    def f(x):
        if not np.all(np.isfinite(x)):
            raise ValueError("f was handed a point that is not finite")
        seen.append(x.copy())
        return float((x - 1) @ (x - 1))

    def answers(problem, options):
        problem.fun(np.array([0.5, 0.5]))
        problem.fun(np.array([0.8, 0.9]))
        return Outcome(np.full(2, np.nan), Status.OPTIMAL, "done", 2)

    name = with_entry(monkeypatch, answers)
    sol = solvers.nlp.minimize(NLPProblem(f, lambda x: 2 * (x - 1), np.zeros(2)), name)
    assert len(seen) == 2 and np.allclose(sol.x, [0.8, 0.9]) and not sol.status.ok


def test_a_point_labelled_optimal_outside_the_rows_is_a_solver_error(monkeypatch):
    """A record claiming linear rows for L-BFGS-B, which ignores them: its unconstrained minimum (1, 1), outside
    x1 + x2 <= 1, was reported OPTIMAL (a tour's plugin), where a QP backend's would be refused (ROW_SLACK)."""
    problem = NLPProblem(lambda x: float((x - 1) @ (x - 1)), lambda x: 2 * (x - 1), np.zeros(2),
                         A=np.ones((1, 2)), lb=[-np.inf], ub=[1.0])
    name = with_entry(monkeypatch, lambda p, o: Outcome(np.ones(2), Status.OPTIMAL, "converged", 3), "slsqp")
    with pytest.raises(SolverError, match=r"^answers: returned a point labelled OPTIMAL that misses row 0 by 0\.5 "):
        solvers.nlp.minimize(problem, name)
    near = lambda p, o: Outcome(np.array([0.5, 0.5 + 1e-4]), Status.OPTIMAL, "converged", 3)  # noqa: E731
    name = with_entry(monkeypatch, near, "slsqp")  # within the slack: a first-order backend's tolerance
    assert solvers.nlp.minimize(problem, name).status is Status.OPTIMAL


def _steps_past_the_bounds(problem, options):
    """Gradient steps that ignore the bounds (a record claiming them)."""
    x = np.array(problem.x0, dtype=float)
    for _ in range(20):
        x = x - 0.5 * problem.grad(x)
        problem.fun(x)
    return Outcome(x, Status.MAX_ITER, "max", 20)


def test_a_backend_claiming_bounds_is_stopped_at_its_first_point_outside_them(monkeypatch):
    """A tour's backend claiming ``bounds`` stepped past them: the time refinement's f got negative durations and the
    run stopped with "P[4, 4] = -1.1e+16 < 0: P must be positive semidefinite", naming no backend. The user's f is
    never called outside the bounds; the error names the backend."""
    seen = []

    def f(x):
        seen.append(x.copy())
        return float((x + 3) @ (x + 3))

    problem = NLPProblem(f, lambda x: 2 * (x + 3), np.ones(2), lower=0.0)
    name = with_entry(monkeypatch, _steps_past_the_bounds)
    with pytest.raises(SolverError, match=r"^answers: evaluated f at x\[0\] = -3, outside its bounds \[0, "
                                          r"inf\], although its record claims bounds$"):
        solvers.nlp.minimize(problem, name)
    assert all(np.all(x >= 0) for x in seen)


def test_a_backend_without_bounds_is_refused_a_bounded_problem(monkeypatch):
    """The record's ``bounds = False`` was read nowhere: such a backend was handed the time refinement's bounded
    durations. Now it is refused, as a backend without linear rows is refused rows."""
    record = dataclasses.replace(dispatch.BACKENDS.get("lbfgsb"), name="free", entry=_steps_past_the_bounds,
                                 capabilities=dataclasses.replace(dispatch.BACKENDS.get("lbfgsb").capabilities,
                                                                  bounds=False))
    real = dispatch.BACKENDS.get
    monkeypatch.setattr(dispatch.BACKENDS, "get", lambda name: record if name == "free" else real(name))
    with pytest.raises(InvalidProblem, match=r"^backend 'free' takes no bounds; this problem has some \(installed "
                                             r"backends that take them: ipopt, "):
        solvers.nlp.minimize(NLPProblem(lambda x: float(x @ x), lambda x: 2 * x, np.ones(2), lower=0.0), "free")
    free = solvers.nlp.minimize(NLPProblem(lambda x: float((x + 3) @ (x + 3)), lambda x: 2 * (x + 3), np.ones(2)),
                                "free")
    assert np.allclose(free.x, -3.0)  # without bounds it is taken
