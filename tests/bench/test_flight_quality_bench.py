"""The refinement's cost lines of experiments/bench/flight_quality.py."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parents[2] / "experiments" / "bench"))
from flight_quality import cost_lines  # noqa: E402


def row(case: str, code: str, variant: str, plan_s: float, run_s: float | None) -> dict:
    return {"case": case, "code": code, "variant": variant, "plan_s": plan_s, "run_s": run_s}


def test_refined_over_default_per_case_and_code():
    rows = [row("forest", "HEAD", "default", 0.5, 2.0), row("forest", "HEAD", "refined", 2.0, 4.0),
            row("forest", "now", "default", 0.4, 2.5), row("forest", "now", "refined", 1.2, 3.0),
            row("trap", "now", "refined", 1.0, 3.0)]  # no default to compare with: no line
    assert cost_lines(rows) == ["refined / default, forest (HEAD): plan_s 4.00 x, run_s 2.00 x",
                                "refined / default, forest (now): plan_s 3.00 x, run_s 1.20 x"]


def test_a_baseline_without_run_s_gets_a_dash():
    rows = [row("rooms", "abc", "default", 1.0, None), row("rooms", "abc", "refined", 2.5, None)]
    assert cost_lines(rows) == ["refined / default, rooms (abc): plan_s 2.50 x, run_s -"]


def test_repeated_rounds_give_the_median_of_the_ratios_within_each_round():
    rows = []
    # round 1's refined run was slow (a busy machine): its own default was slow too, the ratio holds
    for k, (d, r) in enumerate([(1.0, 3.2), (2.0, 5.0), (1.0, 2.6)]):
        rows += [{**row("clutter40", "now", "default", d, 2 * d), "round": k, "makespan_s": 46.7, "steps": 61},
                 {**row("clutter40", "now", "refined", r, 2 * r), "round": k, "makespan_s": 43.1, "steps": 61}]
    assert cost_lines(rows) == ["refined / default, clutter40 (now, median of 3 rounds): plan_s 2.60 x, run_s 2.60 x"]


def test_a_round_that_flies_differently_is_reported():
    rows = [{**row("arena8", "now", "default", 1.0, 2.0), "round": k, "makespan_s": m, "steps": 16}
            for k, m in enumerate([5.78, 5.78, 5.81])]
    assert cost_lines(rows) == ["arena8 (now) default: round 2 flew 5.81 s in 16 steps, round 0 5.78 s in 16"]


def test_keys_the_running_code_does_not_know_are_dropped_for_a_baseline():
    """A baseline refuses keys added after it (``unknown config key mrf.follow``): the benches drop from a case the
    keys the imported code's config lacks, and keep the rest, nested tables whole."""
    from baseline_code import drop_unknown_keys

    data = {"mrf": {"follow": False, "added_later": 1}, "scenario": {"map": {"kind": "free", "size": [8, 8]},
                                                                    "later_key": 2},
            "smoothing": {"v_max": 1.0}}
    drop_unknown_keys(data)
    assert data == {"mrf": {"follow": False}, "scenario": {"map": {"kind": "free", "size": [8, 8]}},
                    "smoothing": {"v_max": 1.0}}


def test_the_queue_cases_are_the_tours_maps():
    """funnel20 and halls50: one gap one cell wide, three corridors two wide, every robot starting free."""
    import numpy as np
    from flight_quality import case_config

    from mrfswarm.config import from_dict
    from mrfswarm.scenario import build_scenario

    widths = {}
    for case, wall in (("funnel20", 20), ("halls50", 24)):
        data, base = case_config(case)
        scn = build_scenario(from_dict(data, base))
        free = scn.grid.free
        widths[case] = int(free[wall].sum())
        assert free[tuple(np.asarray(scn.start).T)].all() and len(scn.start) == data["scenario"]["start"]["n_robots"]
    assert widths == {"funnel20": 1, "halls50": 6}
