"""Every registered NLP backend against known optima, on its options, and on its errors.

The backends come from the one registry (``solvers.nlp.BACKENDS``); a backend that is not
installed is skipped. References are in ``support/nlp_reference.py`` (analytic, or built
from a chosen KKT point); no backend makes a reference. The time refinement's own problem
is in ``test_time_allocation.py``.
"""

from __future__ import annotations

import subprocess
import sys
import time

import numpy as np
import pytest

from solvers import nlp
from solvers.errors import InvalidProblem, SolverError, SolverNotFound
from solvers.nlp import dispatch, lbfgsb_, trust_constr_
from solvers.nlp.capabilities import NLPCapabilities
from solvers.nlp.solution import Outcome
from solvers.registry import Backend, Registry
from support import nlp_reference as refs
from support.repository import ROOT, cites_a_year, declared_extras

NAMES = nlp.BACKENDS.names()
REFERENCES = refs.all_references()

# agreement demanded of every backend with default Options (tol 1e-8); trust-constr's interior
# point ends 4e-6 inside an active linear row (objective 5.7e-6 above the minimum), the others
# within 1e-7
OBJ_TOL = 1e-5  # relative to max(1, |f*|)
X_TOL = 1e-5


def installed(name: str) -> None:
    if name not in nlp.available():
        pytest.skip(f"NLP backend {name} is not installed")


def capabilities(name: str) -> NLPCapabilities:
    return nlp.BACKENDS.get(name).capabilities


def assert_agrees(sol: nlp.Solution, x_ref: np.ndarray, f_ref: float, what: str = "") -> None:
    assert sol.status.ok, f"{sol.backend}{what}: {sol.status} ({sol.raw_status})"
    assert abs(sol.objective - f_ref) <= OBJ_TOL * max(1.0, abs(f_ref)), (
        f"{sol.backend}{what}: objective {sol.objective!r} vs reference {f_ref!r}")
    dx = np.abs(sol.x - x_ref).max()
    assert dx <= X_TOL * max(1.0, np.abs(x_ref).max()), f"{sol.backend}{what}: |x - x_ref|_inf = {dx:.2e}"


# ------------------------------------------------------------------ known answers


@pytest.mark.parametrize("ref", REFERENCES, ids=lambda r: r.name)
@pytest.mark.parametrize("name", NAMES, ids=str)
def test_known_optimum(name, ref):
    installed(name)
    if ref.has_linear_rows and not capabilities(name).linear_constraints:
        with pytest.raises(InvalidProblem, match="bounds only"):
            nlp.minimize(ref.problem, name)
        return
    sol = nlp.minimize(ref.problem, name)
    assert_agrees(sol, ref.x, ref.objective)
    assert ref.problem.max_violation(sol.x) <= 1e-7
    assert sol.backend == name and sol.iterations >= 1 and sol.evaluations >= 1 and sol.gradient_evaluations >= 1
    assert sol.solve_time_s > 0 and sol.setup_time_s >= 0


@pytest.mark.parametrize("name", NAMES, ids=str)
def test_evaluations_stay_inside_the_bounds_and_are_counted(name):
    """``bounds``: f is never evaluated outside the box; dispatch counts every call the backend makes."""
    installed(name)
    assert capabilities(name).bounds
    ref = refs.bounded_rosenbrock()
    p = ref.problem
    seen: list[np.ndarray] = []
    grads = [0]

    def fun(x):
        seen.append(np.array(x))
        return p.fun(x)

    def grad(x):
        grads[0] += 1
        return p.grad(x)

    sol = nlp.minimize(p.with_functions(fun, grad), name)
    assert_agrees(sol, ref.x, ref.objective)
    outside = [x for x in seen if np.any(x < p.lower) or np.any(x > p.upper)]
    assert outside == [], f"{name} evaluated f outside the bounds at {outside[:3]}"
    assert sol.evaluations == len(seen) and sol.gradient_evaluations == grads[0]


@pytest.mark.parametrize("x0", [[2.0, -2.0], [0.5, 0.5], [1.5, 2.0]], ids=["corner", "on_lower", "on_upper"])
@pytest.mark.parametrize("name", NAMES, ids=str)
def test_a_start_on_a_bound_reaches_the_minimum(name, x0):
    """Rosenbrock in [-2, 2] x [-2, 2] (x >= 0.5 for the start on a lower bound), started on a bound: trust-constr,
    whose barrier keeps bounds by slacks that are 0 there, never moved off it and called the start point (f = 3601
    at the corner) or a point on that bound (f = 0.25) optimal. Every backend reaches (1, 1)."""
    installed(name)
    lower = [0.5 if x0 == [0.5, 0.5] else -2.0, -2.0]
    sol = nlp.minimize(nlp.NLPProblem(refs._rosenbrock, refs._rosenbrock_grad, x0, lower, 2.0), name)
    assert_agrees(sol, np.ones(2), 0.0)


@pytest.mark.parametrize("name", NAMES, ids=str)
def test_nan_region_is_stepped_back_from(name):
    """f undefined (NaN) on part of the box, entered by the first steps: every backend still
    reaches the minimum, natively (``nan_step_back``) or through dispatch's substitute value."""
    installed(name)
    region = refs.NaNRegion()
    sol = nlp.minimize(region.problem(), name)
    assert region.hits > 0, f"{name} never entered the undefined region: the test tests nothing"
    assert_agrees(sol, region.x, region.objective)


@pytest.mark.parametrize("solve", [lbfgsb_.solve, trust_constr_.solve], ids=["lbfgsb", "trust_constr"])
def test_without_the_nan_substitute_these_backends_stop_at_the_first_nan(solve):
    """The guard of ``solvers.nlp.evaluation``: called without it, L-BFGS-B's line search ends
    'abnormal' and trust-constr stalls at the start (so the substitute is what makes them work)."""
    region = refs.NaNRegion()
    out = solve(region.problem(), nlp.Options())
    assert not (out.status.ok and np.allclose(out.x, region.x, atol=1e-4)), out
    assert not nlp.BACKENDS.get("lbfgsb").capabilities.nan_step_back
    assert not nlp.BACKENDS.get("trust_constr").capabilities.nan_step_back


def test_a_point_where_f_is_nan_is_never_reported_optimal(monkeypatch):
    """A backend that claims success at a point where f is NaN (sqpmethod did, after a failed
    line search) is reported ``ERROR``."""
    region = refs.NaNRegion()

    def liar(problem, options):
        return Outcome(x=np.full(3, 0.5), status=nlp.Status.OPTIMAL, raw_status="Solve_Succeeded", iterations=1)

    fake = Backend(name="liar", entry=liar, capabilities=NLPCapabilities(
        bounds=True, linear_constraints=True, needs_gradient=True, quasi_newton=True, nan_step_back=True,
        time_limit_native=False))
    monkeypatch.setattr(dispatch, "BACKENDS", Registry("NLP", [fake]))
    sol = nlp.minimize(region.problem(), "liar")
    assert np.isnan(sol.objective) and sol.status is nlp.Status.ERROR and sol.raw_status == "Solve_Succeeded"


# ------------------------------------------------------------------ options


@pytest.mark.parametrize("name", NAMES, ids=str)
def test_iteration_cap(name):
    installed(name)
    sol = nlp.minimize(refs.rosenbrock().problem, name, nlp.Options(max_iter=3))
    assert sol.status is nlp.Status.MAX_ITER and sol.iterations <= 3, (sol.status, sol.iterations)


@pytest.mark.parametrize("name", NAMES, ids=str)
def test_time_limit(name):
    """Each evaluation takes 20 ms; a 0.2 s limit stops a run that needs far more evaluations."""
    installed(name)
    ref = refs.rosenbrock()

    def slow(x):
        time.sleep(0.02)
        return ref.problem.fun(x)

    problem = ref.problem.with_functions(slow, ref.problem.grad)
    sol = nlp.minimize(problem, name, nlp.Options(time_limit=0.2))
    assert sol.status is nlp.Status.TIME_LIMIT, (sol.status, sol.raw_status)
    assert sol.evaluations < nlp.minimize(ref.problem, name).evaluations


@pytest.mark.parametrize("name", NAMES, ids=str)
def test_tolerance_reaches_the_backend(name):
    """A loose tolerance stops earlier than the default one."""
    installed(name)
    problem = refs.rosenbrock().problem
    loose = nlp.minimize(problem, name, nlp.Options(tol=1e-2))
    tight = nlp.minimize(problem, name)
    assert loose.evaluations < tight.evaluations and abs(loose.objective) > abs(tight.objective)


def test_options_are_checked():
    with pytest.raises(ValueError, match="tol"):
        nlp.Options(tol=0)
    with pytest.raises(ValueError, match="max_iter"):
        nlp.Options(max_iter=0)
    with pytest.raises(ValueError, match="time_limit"):
        nlp.Options(time_limit=-1.0)
    with pytest.raises(TypeError):
        nlp.Options(eps_abs=1e-3)  # type: ignore[call-arg]  # the QP's name: not an NLP option


# ------------------------------------------------------------------ errors


class Boom(Exception):
    pass


@pytest.mark.parametrize("name", NAMES, ids=str)
def test_an_error_of_the_callable_reaches_the_caller_as_itself(name, capfd):
    """Also through CasADi, which turns it into its own RuntimeError; and quietly: through Ipopt and sqpmethod the
    caller got the right exception after a Python traceback and CasADi's lines on stderr."""
    installed(name)
    p = refs.rosenbrock().problem

    def fun(x):
        if x[0] > -1.0:
            raise Boom("cannot evaluate")
        return p.fun(x)

    with pytest.raises(Boom, match="cannot evaluate"):
        nlp.minimize(p.with_functions(fun, p.grad), name)
    printed = capfd.readouterr()
    assert "Traceback" not in printed.err + printed.out and "Boom" not in printed.err + printed.out


@pytest.mark.parametrize("name", NAMES, ids=str)
def test_a_gradient_of_the_wrong_size_is_an_invalid_problem(name):
    installed(name)
    p = refs.rosenbrock().problem
    with pytest.raises(InvalidProblem, match="grad returned 3 entries, the problem has 2 variables"):
        nlp.minimize(p.with_functions(p.fun, lambda x: np.zeros(3)), name)


@pytest.mark.parametrize("name", NAMES, ids=str)
@pytest.mark.parametrize("value, shown", [(np.array([1.0, 2.0]), r"array\(\[1\., 2\.\]\)"), ("a", "'a'"),
                                          (None, "None")], ids=["two values", "a string", "None"])
def test_a_value_of_f_that_is_not_one_number_is_an_invalid_problem(name, value, shown):
    """f returning an array of two values ended in NumPy's "only 0-dimensional arrays can be converted to Python
    scalars", a string in "could not convert string to float", naming no callable (a library tour)."""
    installed(name)
    p = refs.rosenbrock().problem
    with pytest.raises(InvalidProblem, match=rf"^fun returned {shown}: must be one real number$"):
        nlp.minimize(p.with_functions(lambda x: value, p.grad), name)


@pytest.mark.parametrize("name", NAMES, ids=str)
def test_a_value_of_f_of_one_element_is_taken(name):
    installed(name)
    p = refs.rosenbrock().problem
    got = nlp.minimize(p.with_functions(lambda x: np.array([p.fun(x)]), p.grad), name)
    assert got.objective == pytest.approx(nlp.minimize(p, name).objective, abs=1e-9)


def test_a_backend_failure_is_a_solver_error(monkeypatch):
    def broken(problem, options):
        raise RuntimeError("native crash")

    fake = Backend(name="broken", entry=broken, capabilities=NLPCapabilities(
        bounds=True, linear_constraints=True, needs_gradient=True, quasi_newton=True, nan_step_back=True,
        time_limit_native=False))
    monkeypatch.setattr(dispatch, "BACKENDS", Registry("NLP", [fake]))
    with pytest.raises(SolverError, match="broken failed: RuntimeError: native crash") as info:
        nlp.minimize(refs.rosenbrock().problem, "broken")
    assert info.value.backend == "broken"


def test_linear_rows_are_refused_by_a_bounds_only_backend():
    installed("lbfgsb")
    with pytest.raises(InvalidProblem, match=r"'lbfgsb' takes bounds only.*installed backends that take them: ipopt"):
        nlp.minimize(refs.linear_rows_quadratic().problem, "lbfgsb")


def test_problem_validation():
    f, g = refs.rosenbrock().problem.fun, refs.rosenbrock().problem.grad
    with pytest.raises(InvalidProblem, match=r"x0\[0\] = 3.0 is outside its bounds"):
        nlp.NLPProblem(f, g, [3.0, 0.0], -1.0, 1.0)
    with pytest.raises(InvalidProblem, match=r"lower\[1\] = 2.0 > upper\[1\] = 1.0"):
        nlp.NLPProblem(f, g, [0.0, 0.0], [0.0, 2.0], 1.0)
    with pytest.raises(InvalidProblem, match=r"A has shape \(1, 3\), expected \(m, 2\)"):
        nlp.NLPProblem(f, g, [0.0, 0.0], A=np.ones((1, 3)))
    with pytest.raises(InvalidProblem, match="upper has 3 entries, expected 2"):
        nlp.NLPProblem(f, g, [0.0, 0.0], 0.0, [1.0, 1.0, 1.0])
    with pytest.raises(InvalidProblem, match="x0 must be finite"):
        nlp.NLPProblem(f, g, [np.nan, 0.0])
    with pytest.raises(InvalidProblem, match="callables"):
        nlp.NLPProblem(f, None, [0.0, 0.0])  # type: ignore[arg-type]
    p = nlp.NLPProblem(f, g, [0.0, 0.0], A=np.ones((1, 2)), lb=-np.inf, ub=np.inf)
    assert p.m == 1 and not p.has_linear_rows  # a row free on both sides constrains nothing


# ------------------------------------------------------------------ registry, records, availability


@pytest.fixture
def missing_nlp_backend():
    return Backend(name="ghost", entry=lambda *a: None, requires=("no_such_module_xyz",), extra="ghost",
                   capabilities=NLPCapabilities(bounds=True, linear_constraints=False, needs_gradient=True,
                                                quasi_newton=True, nan_step_back=False, time_limit_native=False))


def test_missing_backend_is_reported_with_its_extra(missing_nlp_backend):
    reg = Registry("NLP", [nlp.BACKENDS.get("lbfgsb"), missing_nlp_backend])
    assert reg.available() == ["lbfgsb"]
    with pytest.raises(SolverNotFound, match=r"NLP backend 'ghost' is not installed.*no_such_module_xyz.*"
                                             r"mrfswarm\[ghost\].*installed: lbfgsb"):
        reg.get("ghost")


def test_unknown_backend_names_every_installed_one():
    with pytest.raises(SolverNotFound, match="unknown NLP backend 'nope'") as info:
        nlp.minimize(refs.rosenbrock().problem, backend="nope")
    for name in nlp.available():
        assert name in str(info.value)


@pytest.mark.parametrize("name", NAMES, ids=str)
def test_backend_record(name):
    b = next(x for x in nlp.BACKENDS if x.name == name)
    # a plugin's extra is its own distribution's (docs/extending.md, "Outside the package")
    assert b.extra == "" or b.extra in declared_extras(b.distribution), \
        f"{name}: extra {b.extra!r} not declared by {b.distribution or 'pyproject.toml'}"
    assert b.requires and callable(b.entry) and isinstance(b.capabilities, NLPCapabilities)
    doc = sys.modules[b.entry.__module__].__doc__
    assert cites_a_year(doc), f"{name}: the module docstring cites no paper with its year"
    assert b.summary


def test_importing_solvers_nlp_imports_no_native_backend():
    code = ("import sys, solvers.nlp; "
            "print(sorted(m for m in ('casadi', 'scipy.optimize') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         env={"PYTHONPATH": str(ROOT), "PATH": ""}).stdout.strip()
    assert out == "[]"
