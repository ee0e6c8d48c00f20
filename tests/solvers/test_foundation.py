"""The registries, the standard forms and the CLI's error contract."""

import numpy as np
import pytest
import scipy.sparse as sp

import solvers
from mrfswarm.cli import main
from solvers import mrf, qp
from solvers.errors import InvalidProblem, SolverNotFound
from solvers.registry import Registry


def test_unknown_backend_names_installed_ones():
    with pytest.raises(SolverNotFound, match="installed: .*osqp"):
        qp.BACKENDS.get("nope")


def test_qp_problem_validation():
    P, q = sp.eye(2), np.zeros(2)
    A = sp.csc_matrix(np.ones((1, 2)))
    with pytest.raises(InvalidProblem, match="l\\[0\\]"):
        qp.QPProblem(P=P, q=q, A=A, l=np.array([2.0]), u=np.array([1.0]))
    with pytest.raises(InvalidProblem, match="symmetric"):
        qp.QPProblem(P=sp.csc_matrix(np.array([[1.0, 1.0], [0.0, 1.0]])), q=q, A=A, l=np.zeros(1), u=np.ones(1))
    with pytest.raises(InvalidProblem, match="finite"):
        qp.QPProblem(P=P, q=np.array([np.nan, 0.0]), A=A, l=np.zeros(1), u=np.ones(1))
    # a row no x meets: OSQP answered "optimal" at x ~ 1e29, CasADi with a page of its internals
    for l, u in (([np.inf], [np.inf]), ([-np.inf], [-np.inf])):
        with pytest.raises(InvalidProblem, match="row 0.*no x meets it"):
            qp.QPProblem(P=P, q=q, A=A, l=np.array(l), u=np.array(u))
    # P = -I: most backends returned "optimal" at the maximizer of an unbounded problem
    with pytest.raises(InvalidProblem, match="P\\[0, 0\\] = -1 < 0: P must be positive semidefinite"):
        qp.QPProblem(P=-sp.eye(2), q=q, A=A, l=np.ones(1), u=np.ones(1))
    qp.QPProblem(P=sp.csc_matrix(np.diag([1.0, -1e-16])), q=q, A=A, l=np.ones(1), u=np.ones(1))  # rounding
    # no rows: A, l and u may all be None ("l and u must have shape (0,), got (1,) and (1,)" before, a solver tour)
    free = qp.QPProblem(P=P, q=np.ones(2), A=None, l=None, u=None)
    assert free.l.shape == free.u.shape == (0,) and free.A.shape == (0, 2)
    with pytest.raises(InvalidProblem, match="^l and u are needed with A's 1 rows"):
        qp.QPProblem(P=P, q=q, A=A, l=None, u=np.ones(1))


def test_nlp_problem_refuses_bounds_no_x_meets():
    from solvers.nlp import NLPProblem

    def f(x):
        return float(x @ x)

    def g(x):
        return 2 * x

    with pytest.raises(InvalidProblem, match="A x: lower\\[0\\] = inf, upper\\[0\\] = inf: no x meets it"):
        NLPProblem(f, g, np.zeros(2), A=np.ones((1, 2)), lb=np.inf, ub=np.inf)
    with pytest.raises(InvalidProblem, match="lower\\[1\\] = -inf, upper\\[1\\] = -inf"):
        NLPProblem(f, g, np.zeros(2), lower=-np.inf, upper=np.array([1.0, -np.inf]))


def test_mrf_problem_rejects_infeasible_initial():
    with pytest.raises(InvalidProblem, match="initial"):
        mrf.PairwiseMRF(
            unary=np.zeros((2, 2)), edges=np.zeros((0, 2)), pairwise=np.zeros((0, 2, 2)),
            conflicts=[[0, 1]], conflict_mask=[[[True, False], [False, False]]], initial=[0, 0],
        )


def test_mrf_problem_checks_its_shapes():
    """Arrays of the wrong shape were reshaped into other problems: 3 edges given as (2, 3) were read as other
    edges, one table for 2 edges as two; a label 0.7 was read as 0."""
    base = dict(unary=np.zeros((3, 2)), edges=[[0, 1], [1, 2]], pairwise=np.zeros((2, 2, 2)),
                conflicts=np.zeros((0, 2)), conflict_mask=np.zeros((0, 2, 2), bool), initial=[0, 0, 0])
    mrf.PairwiseMRF(**base)
    for key, value, message in (("edges", [[0, 1, 2], [1, 2, 0]], r"edges must have shape \(m, 2\), got \(2, 3\)"),
                                ("pairwise", np.zeros((1, 4, 2)), r"pairwise must have shape \(m, 2, 2\), got \(1, 4, 2\)"),
                                ("pairwise", np.zeros((2, 3, 3)), r"pairwise must have shape \(m, 2, 2\)"),
                                ("initial", [0.7, 0, 0], "initial must hold whole numbers")):
        with pytest.raises(InvalidProblem, match=message):
            mrf.PairwiseMRF(**{**base, key: value})


@pytest.mark.parametrize("key, value", [("edges", [[False, True], [True, False]]), ("conflicts", [[False, True]]),
                                        ("initial", [False, False, True])])
def test_mrf_problem_refuses_booleans_as_indices(key, value):
    """[[False, True]] as edges was read as the edge (0, 1), silently; a bool mask where indices belong."""
    base = dict(unary=np.zeros((3, 2)), edges=[[0, 1], [1, 2]], pairwise=np.zeros((2, 2, 2)),
                conflicts=np.zeros((0, 2)), conflict_mask=np.zeros((0, 2, 2), bool), initial=[0, 0, 0])
    if key == "conflicts":
        base["conflict_mask"] = np.zeros((1, 2, 2), bool)
    with pytest.raises(InvalidProblem, match=rf"^{key} = .*must hold integer indices, not booleans"):
        mrf.PairwiseMRF(**{**base, key: value})


def test_repair_returns_feasible_labelling():
    rng = np.random.default_rng(0)
    N, L = 6, 3
    conflicts = np.array([[i, j] for i in range(N) for j in range(i + 1, N)])
    mask = rng.random((len(conflicts), L, L)) < 0.3
    mask[:, 0, 0] = False  # the all-zero labelling is feasible
    m = mrf.PairwiseMRF(unary=np.zeros((N, L)), edges=np.zeros((0, 2)), pairwise=np.zeros((0, L, L)),
                        conflicts=conflicts, conflict_mask=mask, initial=np.zeros(N, int))
    for _ in range(20):
        x = rng.integers(0, L, N)
        y, n = mrf.repair(m, x)
        assert m.is_feasible(y)
        assert n == np.count_nonzero(y != x)


def test_solvers_command_lists_every_registered_backend(capsys):
    assert main(["solvers"]) == 0
    out = capsys.readouterr().out
    assert "NLP backends (--nlp)" in out
    for b in list(solvers.qp.BACKENDS) + list(solvers.nlp.BACKENDS) + list(solvers.mrf.METHODS):
        assert b.name in out
        assert f"[{', '.join(b.capabilities.flags()) or 'none'}]" in out  # what the record says it can do
    # the config's defaults are marked, one per registry
    defaults = [line.split()[0] for line in out.splitlines() if "the run's default" in line and line.startswith("  ")]
    assert defaults == ["piqp", "ipopt", "icm"]
    # and the solver layer's own defaults, which are not all the run's (a solver tour read one for the other)
    assert (f"solvers.qp.solve() uses {solvers.qp.DEFAULT_BACKEND!r}, solvers.nlp.minimize() "
            f"{solvers.nlp.DEFAULT_BACKEND!r}") in out


def test_bad_options_are_invalid_options_naming_the_field():
    """Options of the wrong type failed with Python's own TypeError ("'<' not supported between instances of 'str'
    and 'int'"), out of range with a bare ValueError: both are InvalidOptions now (a ValueError still)."""
    from solvers import InvalidOptions, nlp

    for make, message in ((lambda: qp.Options(max_iter="10"), r"Options.max_iter = '10': must be int"),
                          (lambda: mrf.Options(seed="x"), r"Options.seed = 'x': must be int"),
                          (lambda: nlp.Options(time_limit="1"), r"Options.time_limit = '1': must be float or None"),
                          (lambda: qp.Options(eps_abs=-1.0), "tolerances must be positive"),
                          (lambda: mrf.Options(cooling=2.0), r"cooling must be in \(0, 1\)")):
        with pytest.raises(InvalidOptions, match=message) as e:
            make()
        assert isinstance(e.value, (solvers.SolversError, ValueError))
    assert qp.Options(max_iter=np.int64(5), eps_abs=np.float64(1e-6), time_limit=None).max_iter == 5


@pytest.mark.parametrize("make, message", [
    (lambda: qp.Options(eps_abs=np.inf), r"^tolerances must be positive and finite \(eps_rel may be 0\), got eps_abs=inf"),
    (lambda: qp.Options(eps_rel=np.inf), r"^tolerances must be positive and finite .*eps_rel=inf$"),
    (lambda: solvers.nlp.Options(tol=np.inf), r"^tol must be positive and finite, got inf$"),
    (lambda: mrf.Options(tol=np.inf), r"^tol must be finite and >= 0, got inf$"),
], ids=["qp_eps_abs", "qp_eps_rel", "nlp_tol", "mrf_tol"])
def test_an_infinite_tolerance_is_refused(make, message):
    """An infinite tolerance was taken: on the README's QP (optimum (0.5, 0.5)) ipopt called (0, 0) optimal and
    piqp, proxsuite, clarabel and cvxpy returned points that miss its row; every NLP backend called its start point
    optimal; the lazy flipper never moved. SCS alone refused it, in its own words."""
    with pytest.raises(solvers.InvalidOptions, match=message):
        make()


def test_the_two_roots_of_the_errors():
    """The numerical layer's root is its own; the domain's derives from it; the CLI catches both."""
    from mrfswarm.errors import ConfigError, MrfswarmError, PlanError

    assert solvers.SolversError.__name__ == "SolversError" and not issubclass(solvers.SolversError, MrfswarmError)
    for cls in (SolverNotFound, InvalidProblem, solvers.InvalidOptions, solvers.SolverError, solvers.InfeasibleError):
        assert issubclass(cls, solvers.SolversError) and not issubclass(cls, MrfswarmError)
    for cls in (MrfswarmError, ConfigError, PlanError):
        assert issubclass(cls, solvers.SolversError)


def test_install_hint_is_read_from_the_installed_metadata(monkeypatch, missing_qp_backend):
    """The layer does not name the distribution that installs it: the hint comes from the metadata,
    and without any (the package run from a source tree) it names the extra only."""
    from solvers import registry

    assert missing_qp_backend.install_hint == 'pip install "mrfswarm[ghost]"'
    monkeypatch.setattr(registry, "_distribution", lambda: None)
    assert missing_qp_backend.install_hint == "install the 'ghost' extra"
    with pytest.raises(SolverNotFound, match="install the 'ghost' extra"):
        Registry("QP", [missing_qp_backend]).get("ghost")


def test_solvers_never_imports_or_names_mrfswarm():
    """Neither an import nor a string of the numerical layer names the domain package."""
    import pathlib
    root = pathlib.Path(solvers.__file__).parent
    offenders = [str(p) for p in root.rglob("*.py") if "mrfswarm" in "".join(
        line for line in p.read_text().splitlines() if line.lstrip().startswith(("import ", "from ")))]
    assert offenders == []
    named = [str(p) for p in root.rglob("*.py") if "mrfswarm[" in p.read_text() or "MrfswarmError" in p.read_text()]
    assert named == []


def test_public_api_and_a_quiet_import():
    import subprocess
    import sys

    code = ("import sys, mrfswarm, solvers\n"
            "assert callable(mrfswarm.plan) and callable(mrfswarm.load_config)\n"
            "assert callable(solvers.qp.solve) and callable(solvers.mrf.minimize)\n"
            "heavy = [m for m in ('matplotlib', 'rotorpy', 'dask', 'cvxpy', 'piqp', 'proxsuite', 'torch') if m in sys.modules]\n"
            "assert not heavy, heavy\n")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr


def test_a_backend_citation_of_any_year_counts():
    """The QP backends' record test took years 1990 to 2029 only and refused a backend citing SLSQP (Kraft,
    1988), which docs/extending.md asks for ("cites its paper with its year"); a library tour."""
    from support.repository import cites_a_year

    assert cites_a_year('Kraft, "A software package for sequential quadratic programming" (1988).')
    assert cites_a_year("Goldfarb, Idnani, Math. Programming 27 (1983)") and cites_a_year("a paper of 2031")
    assert not cites_a_year("no paper here, version 0.12345") and not cites_a_year(None)
