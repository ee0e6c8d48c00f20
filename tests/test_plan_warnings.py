"""What a finished plan warns of reaches a Python caller of :func:`mrfswarm.plan` as :class:`PlanWarning`.

``mrfswarm run`` printed these lines after its summary (windows flown as their rest-to-rest witness, robots short of
the goal, ...), and ``plan`` said none of them: with ``smoothing.qp_options.max_iter = 1`` every window of free5 flew
its witness, 13.3 s of flight instead of 4.7 s, without a word to the caller.
"""

import warnings

import pytest

import mrfswarm
from mrfswarm.config import load_config
from mrfswarm.errors import PlanWarning
from support.repository import EXPERIMENTS

OFF = ["simulation.enabled=false"]


def test_windows_flown_as_their_witness_are_said_to_the_caller():
    cfg = load_config(EXPERIMENTS / "free5.toml", [*OFF, "smoothing.qp_options.max_iter=1"])
    with pytest.warns(PlanWarning, match=r"smoothing windows had no solution at their planned durations and fly the "
                                         r"rest-to-rest witness \(slower, with stops\)") as record:
        result = mrfswarm.plan(cfg, progress=False)
    s = result.summary()
    assert s["window_attempts"].get("witness", 0) == s["windows"] > 0
    said = [str(w.message) for w in record if w.category is PlanWarning]
    assert said == result.warnings() and said[0].startswith(f"{s['windows']} of {s['windows']} smoothing windows")
    assert {w.filename for w in record if w.category is PlanWarning} == {__file__}  # pointing at the caller


def test_a_clean_plan_warns_nothing():
    cfg = load_config(EXPERIMENTS / "corridor.toml", OFF)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = mrfswarm.plan(cfg, progress=False)
    assert result.warnings() == []
    assert [str(w.message) for w in caught if issubclass(w.category, PlanWarning)] == []


def test_robots_cut_at_max_steps_are_said_to_the_caller():
    cfg = load_config(EXPERIMENTS / "corridor.toml", [*OFF, "smoothing.enabled=false", "mrf.max_steps=3"])
    with pytest.warns(PlanWarning, match=r"the discrete plan ended at mrf.max_steps = 3 with 5 robots on the way"):
        mrfswarm.plan(cfg, progress=False)


def test_the_command_writes_a_plan_warning_as_one_line(capsys):
    """A command that plans through ``plan`` and does not print its warnings itself (``mrfswarm figs``) writes them
    as the command's own lines, not in Python's format (file, line, source line)."""
    from mrfswarm.cli import _one_line

    def python_format(*args):
        raise AssertionError(f"shown in Python's format: {args}")

    _one_line(python_format)("2 of 2 smoothing windows had no solution", PlanWarning, "x.py", 1)
    assert capsys.readouterr().err == "mrfswarm: warning: 2 of 2 smoothing windows had no solution\n"
