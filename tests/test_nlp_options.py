"""``[smoothing.nlp_options]``: the time refinement's NLP options from the config, over the stage's own
(``NLP_OPTIONS``: tol 1e-4, 12 iterations). A solver comparison could not raise the 12 iterations (a solver tour:
``smoothing.nlp_options`` was an unknown key)."""

from __future__ import annotations

import warnings

import pytest

import mrfswarm
import solvers.nlp
from mrfswarm.config import load_config
from mrfswarm.continuous.receding_horizon import NLP_OPTIONS
from mrfswarm.errors import ConfigError, UnusedSettingWarning
from support.repository import EXPERIMENTS

FREE5 = EXPERIMENTS / "free5.toml"
REFINED = ["simulation.enabled=false", "smoothing.time_refinement=true", "smoothing.refinement=nlp"]


def options_used(monkeypatch, overrides: list[str]) -> list[solvers.nlp.Options]:
    """The options of every NLP solve of a refined free5 run (the backend still solves each)."""
    seen: list[solvers.nlp.Options] = []
    minimize = solvers.nlp.minimize

    def spy(problem, backend=None, options=None):
        seen.append(options)
        return minimize(problem, backend, options)

    monkeypatch.setattr(solvers.nlp, "minimize", spy)
    r = mrfswarm.plan(load_config(FREE5, REFINED + overrides), progress=False)
    assert r.continuous.certificate.ok
    return seen


def test_the_config_s_nlp_options_go_over_the_refinement_s_own(monkeypatch):
    default = options_used(monkeypatch, [])
    assert default and all(o == NLP_OPTIONS for o in default)
    mine = options_used(monkeypatch, ["smoothing.nlp_options.max_iter=30", "smoothing.nlp_options.tol=1e-6"])
    assert mine and all(o.max_iter == 30 and o.tol == 1e-6 and o.time_limit == NLP_OPTIONS.time_limit for o in mine)


@pytest.mark.parametrize("override, key", [("smoothing.nlp_options.max_itr=3", "smoothing.nlp_options.max_itr"),
                                           ("smoothing.nlp_options.max_iter=0", "smoothing.nlp_options"),
                                           ("smoothing.nlp_options.tol=\"a\"", "smoothing.nlp_options.tol")])
def test_a_wrong_nlp_option_is_one_line_naming_it(override, key):
    with pytest.raises(ConfigError, match=key.replace(".", r"\.")) as e:
        load_config(FREE5, [override])
    assert "\n" not in str(e.value)


def test_nlp_options_without_the_nlp_refinement_are_said_unused():
    cfg = load_config(FREE5, ["simulation.enabled=false", "smoothing.enabled=false",
                              "smoothing.nlp_options.max_iter=30"])
    with pytest.warns(UnusedSettingWarning, match=r"smoothing\.nlp_options = \{'max_iter': 30\} not used"):
        mrfswarm.plan(cfg, progress=False)
    with warnings.catch_warnings():
        warnings.simplefilter("error", UnusedSettingWarning)
        mrfswarm.plan(load_config(FREE5, ["simulation.enabled=false", "smoothing.enabled=false"]), progress=False)
