"""experiments/bench/nlp_backends.py: its receding horizon benchmarks the first windows' NLP and plans on.

Its ``_refine`` override fell behind the receding horizon's (a ``merged`` argument more) and the script stopped with
a TypeError at its first window; a docs tour found it. A solver tour found that it benchmarked another problem than
the refinement solves: without the row sum(T) <= the QP's sum (``RecedingHorizon._not_longer``), its evaluations at
the multiplier scaling's iteration budget (its config left ``smoothing.refinement = "scaling"``)."""

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parents[2] / "experiments" / "bench"))
import nlp_backends  # noqa: E402
from nlp_backends import BASELINE, SETTINGS, benchmarked  # noqa: E402

from support.repository import EXPERIMENTS  # noqa: E402


def test_the_first_window_is_benchmarked_and_the_flight_planned():
    rh = benchmarked(EXPERIMENTS / "free5.toml", windows=1, backends=["slsqp"])
    flight = rh.run()
    assert [(r["setting"], r["backend"]) for r in rh.rows] == [(s, "slsqp") for s in SETTINGS]
    assert len({r["window"] for r in rh.rows}) == 1
    assert all(r["objective"] <= r["f_start"] for r in rh.rows)
    assert flight.certificate.ok


def test_the_backends_get_the_problem_the_refinement_solves(monkeypatch):
    """The row sum(T) <= the QP's sum for a backend that takes rows, none for L-BFGS-B (bounds only); the run
    refines by Ipopt, whose evaluations run the NLP refinement's QP budget."""
    posed = []
    minimize = nlp_backends.nlp.minimize

    def spy(problem, backend, options):
        posed.append((backend, problem))
        return minimize(problem, backend, options)

    monkeypatch.setattr(nlp_backends.nlp, "minimize", spy)
    rh = benchmarked(EXPERIMENTS / "free5.toml", windows=1, backends=["slsqp", "lbfgsb"])
    assert (rh.cfg.time_refinement, rh.cfg.refinement, rh.cfg.nlp) == (True, "nlp", BASELINE)
    rh.run()
    by_backend = {name: [p for b, p in posed if b == name] for name in ("slsqp", "lbfgsb")}
    assert len(by_backend["slsqp"]) == len(by_backend["lbfgsb"]) == len(SETTINGS)
    for problem in by_backend["slsqp"]:
        assert problem.has_linear_rows and problem.m == 1
        assert np.array_equal(problem.rows, np.ones((1, problem.n)))
        assert problem.ub[0] == problem.x0.sum() and problem.lb[0] == -np.inf
    assert not any(p.has_linear_rows for p in by_backend["lbfgsb"])
