"""``mrf.contested = "auto"`` (the default): the discrete stage plans with each rule of ``AUTO_RULES`` and keeps
the plan with the fewest robots short of the goal, then the one the time grid's model flies soonest."""

from __future__ import annotations

import math
import sys
from dataclasses import replace

import numpy as np
import pytest

import mrfswarm
from mrfswarm.config import apply_overrides, from_dict, load_config
from mrfswarm.discrete import planner as planner_mod
from mrfswarm.discrete.planner import AUTO_RULES, _short_count, _short_way, flight_time, plan_discrete
from mrfswarm.scenario import build_scenario
from support.repository import EXPERIMENTS


def clutter_map() -> dict:
    """40 robots on a 64 x 64 map with 10 % obstacles (seed 3 of the bench's clutter maps)."""
    sys.path.insert(0, str(EXPERIMENTS / "bench"))
    import flight_quality as fq

    occ = fq._random_field(64, 64, 0.10, 3, (8, 8), (55, 55), 5)
    scn = {"map": {"kind": "ascii", "rows": fq._rows(occ)},
           "start": {"center": [8, 8], "n_robots": 40, "sigma": 2.5, "seed": 0}, "goal": [55, 55]}
    return {"scenario": scn, "interaction": {"k": 7}}


def crossing() -> dict:
    """30 robots crossing an open field straight along x."""
    scn = {"map": {"kind": "free", "size": [60, 30]},
           "start": {"center": [8, 15], "n_robots": 30, "sigma": 3.0, "seed": 0}, "goal": [52, 15]}
    return {"scenario": scn, "interaction": {"k": 7}}


def problem_of(data: dict):
    # congestion 5, the default these maps' margins were measured at (at 8 the clutter map's choice is the same, by
    # 2.9 % instead of more than 3)
    cfg = from_dict(apply_overrides(data, ["simulation.enabled=false", "goal_potential.congestion=5"]))
    return cfg, build_scenario(cfg).discrete_problem()


def plan(problem, cfg, rule: str | None = None, max_steps: int | None = None, on_step=None):
    p = problem if rule is None else replace(problem, contested=rule)
    return plan_discrete(p, method=cfg.mrf.method, max_steps=max_steps or cfg.mrf.max_steps, tol=cfg.mrf.tol,
                         patience=cfg.mrf.patience, progress=cfg.mrf.progress, arrival=cfg.mrf.arrival,
                         on_step=on_step)


@pytest.mark.parametrize("data, expect", [(clutter_map, "shared"), (crossing, "downhill")])
def test_auto_keeps_the_plan_the_flight_model_flies_soonest(data, expect):
    """Clutter flies sooner with the cells shared, a straight crossing with them given downhill (its lanes)."""
    cfg, problem = problem_of(data())
    assert problem.contested == "auto" == cfg.mrf.contested  # the default
    plans = {rule: plan(problem, cfg, rule) for rule in AUTO_RULES}
    auto = plan(problem, cfg)
    assert all(_short_count(problem, p.paths[-1]) == 0 for p in plans.values())
    times = {rule: flight_time(problem, p.paths) for rule, p in plans.items()}
    assert auto.contested == expect == min(times, key=times.get)
    assert np.array_equal(auto.paths, plans[expect].paths) and auto.stop_reason == "arrived"
    other = next(r for r in AUTO_RULES if r != expect)
    assert times[expect] < 0.97 * times[other]  # a clear choice, not a tie broken by rounding


def test_a_plan_cut_short_is_not_kept_though_it_flies_sooner(monkeypatch):
    """After a first plan that arrives, every later rule's plan ends after AUTO_STEP_CAP times its steps. Cut at
    half (the cap set to 0.5 here), the second plan flies sooner by the model, as it is short, but leaves robots
    outside the goal region: the first plan is kept."""
    cfg, problem = problem_of(crossing())
    first = plan(problem, cfg, AUTO_RULES[0])
    monkeypatch.setattr(planner_mod, "AUTO_STEP_CAP", 0.5)
    steps: list[int] = []
    auto = plan(problem, cfg, on_step=lambda t, out: steps.append(t))
    cap = math.ceil(0.5 * first.n_steps)
    starts = [k for k, t in enumerate(steps) if t == 1] + [len(steps)]  # each plan's steps start again from 1
    plans = [steps[a:b] for a, b in zip(starts, starts[1:])]
    assert len(plans) >= 2 and plans[0] == list(range(1, first.n_steps + 1))  # "queue" only where robots wait
    assert all(later == list(range(1, cap + 1)) for later in plans[1:])
    cut = plan(problem, cfg, AUTO_RULES[1], max_steps=cap)
    assert _short_count(problem, cut.paths[-1]) > 0
    assert flight_time(problem, cut.paths) < flight_time(problem, first.paths)  # the model alone would take it
    assert auto.contested == AUTO_RULES[0] and np.array_equal(auto.paths, first.paths)


def bend() -> dict:
    """10 robots in a room whose only way out is a bent corridor one cell wide (a new user's map)."""
    rows = ["##############################"] + ["#.......######################"] * 3 + [
        "#...................##########"] + ["#.......###########.##########"] * 3 + [
        "###################.##########"] * 3 + ["###################.####.....#"] * 4 + [
        "###################..........#"] + ["########################.....#"] * 3 + [
        "##############################"]
    scn = {"map": {"kind": "ascii", "rows": rows}, "goal": [26, 15], "goal_radius": 1.0,
           "start": {"center": [4.0, 4.0], "n_robots": 10, "sigma": 2.0, "seed": 0}}
    return {"scenario": scn, "interaction": {"k": 4},
            "mrf": {"patience": 3, "progress": "energy", "follow": False}}


def test_with_robots_short_either_way_the_plan_that_brings_them_nearer_is_kept():
    """On the bend with the paper's patience rule, one rule's plan stops at its start (no step, nothing to fly)
    and the other's comes nearer; both leave every robot short of the goal region. Kept: the nearer one (the
    plan of no step was kept before, for flying sooner, and the run then failed with "the swarm cannot move")."""
    cfg, problem = problem_of(bend())
    plans = {rule: plan(problem, cfg, rule) for rule in AUTO_RULES}
    assert {p.n_steps == 0 for p in plans.values()} == {False, True}
    assert all(_short_count(problem, p.paths[-1]) == 10 for p in plans.values())
    moved = min((rule for rule, p in plans.items() if p.n_steps > 0),
                key=lambda rule: _short_way(problem, plans[rule].paths[-1]))
    assert flight_time(problem, plans[moved].paths) > 0  # the flight model alone prefers the plan of no step
    auto = plan(problem, cfg)
    assert auto.contested == moved and np.array_equal(auto.paths, plans[moved].paths)
    r = mrfswarm.plan(cfg, progress=False)  # the whole run: smoothed, no error
    assert r.discrete.n_steps > 0 and r.continuous is not None


def test_without_a_flight_model_the_longest_moves_decide():
    """With a cruise speed set (no time grid's model), each step counts its longest move in cells."""
    cfg = from_dict(apply_overrides(clutter_map(), ["simulation.enabled=false", "smoothing.enabled=false",
                                                    "smoothing.speed=1.0"]))
    problem = build_scenario(cfg).discrete_problem()
    assert problem.flight is None
    paths = np.array([[[0, 0], [5, 5]], [[1, 1], [5, 6]], [[1, 1], [5, 7]], [[1, 1], [5, 7]]])
    assert flight_time(problem, paths) == pytest.approx(math.sqrt(2) + 1 + 0)
    auto = plan(problem, cfg)
    assert auto.contested == "shared"


def test_a_discrete_only_run_plans_what_the_full_run_flies():
    """``smoothing.enabled = false`` (scoping a big swarm, a sweep) planned another discrete plan: without the
    time grid's flight model its waits were merged and its contested rule picked by cells (a 1000-robot crossing:
    237 merges against 200; new-user tour). The model is the smoothing config's either way now."""
    rows = ["".join("@" if x == 15 and not 9 <= y <= 11 else "." for x in range(30)) for y in range(20)]
    data = {"scenario": {"map": {"kind": "ascii", "rows": rows}, "goal": [25, 10],
                         "start": {"center": [6, 10], "n_robots": 5, "sigma": 1.0, "seed": 0}},
            "interaction": {"k": 3}, "simulation": {"enabled": False}}
    full = mrfswarm.plan(from_dict(data), progress=False)
    alone = mrfswarm.plan(from_dict({**data, "smoothing": {"enabled": False}}), progress=False)
    assert build_scenario(from_dict({**data, "smoothing": {"enabled": False}})).discrete_problem().flight is not None
    np.testing.assert_array_equal(alone.discrete.paths, full.discrete.paths)
    assert alone.discrete.merged_waits == full.discrete.merged_waits


def test_the_run_records_the_rule_it_planned_with():
    """result.json's ``contested``: the rule "auto" picked, or the config's own."""
    data = apply_overrides(crossing(), ["smoothing.enabled=false", "simulation.enabled=false"])
    assert mrfswarm.plan(from_dict(data), progress=False).summary()["contested"] == "downhill"
    paper = load_config(EXPERIMENTS / "corridor.toml", ["smoothing.enabled=false", "simulation.enabled=false"])
    assert mrfswarm.plan(paper, progress=False).summary()["contested"] == "nearest"  # the paper's rule, pinned


def test_queue_is_planned_only_after_a_shared_plan_whose_robots_wait(monkeypatch):
    """The crossing's robots hardly wait in the "shared" plan, so "auto" plans no "queue" (it plans as "shared"
    until robots wait); with the threshold at 0 it does, and keeps the same plan as before here."""
    cfg, problem = problem_of(crossing())
    shared = plan(problem, cfg, "shared")
    assert planner_mod.waits_per_robot(problem, shared.paths) < planner_mod.QUEUE_WAITS

    def plans_made() -> tuple[int, object]:
        steps: list[int] = []
        auto = plan(problem, cfg, on_step=lambda t, out: steps.append(t))
        return steps.count(1), auto

    made, auto = plans_made()
    assert made == len(AUTO_RULES) - 1
    monkeypatch.setattr(planner_mod, "QUEUE_WAITS", 0.0)
    made_all, auto_all = plans_made()
    assert made_all == len(AUTO_RULES)
    assert auto_all.contested == auto.contested and np.array_equal(auto_all.paths, auto.paths)


def test_waits_per_robot_counts_stays_short_of_the_goal_region():
    cfg, problem = problem_of(crossing())
    goal = np.asarray(problem.goal)
    far = goal - [30, 0]
    paths = np.array([[far, goal], [far, goal], [far + [1, 0], goal], [far + [1, 0], goal]])
    assert planner_mod.waits_per_robot(problem, paths) == pytest.approx(2 / 2)  # robot 0 twice; robot 1 at the goal
    assert planner_mod.waits_per_robot(problem, paths[:1]) == 0.0


def test_without_arrival_a_plan_cut_at_the_cap_is_not_kept():
    """With ``mrf.arrival = false`` the first plan settles with every robot in the goal region, and a later rule's
    plan cut at AUTO_STEP_CAP times its steps can have them there too and fly sooner, unsettled. It was kept,
    reported stopped by "max_steps" at 10 steps under mrf.max_steps = 300 (20 robots packed in an 8 x 8 room;
    stress tour). A plan cut by the cap is never kept."""
    data = {"scenario": {"map": {"kind": "free", "size": [8, 8]}, "goal": [7, 7],
                         "start": {"center": [2, 2], "n_robots": 20, "sigma": 1.5, "seed": 3}},
            "mrf": {"arrival": False}}
    cfg, problem = problem_of(data)
    first = plan(problem, cfg, AUTO_RULES[0])
    assert first.stop_reason != "max_steps" and _short_count(problem, first.paths[-1]) == 0
    auto = plan(problem, cfg)
    assert auto.stop_reason != "max_steps" and auto.n_steps < cfg.mrf.max_steps


def test_auto_picks_by_the_fast_profile_and_merges_by_the_moderate_one():
    """The scenario's problem carries two flight models: ``pick`` (the time grid's fast profile, the attempt every
    window tries first) for the choice of "auto", ``flight`` (the moderate one) for the merged waits."""
    from mrfswarm.continuous.receding_horizon import PROFILES, motion_acceleration

    cfg, problem = problem_of(crossing())
    s = cfg.smoothing
    for model, name in ((problem.pick, "fast"), (problem.flight, "moderate")):
        _, cruise, acc = next(p for p in PROFILES if p[0] == name)
        assert model.v_max == pytest.approx(cruise * s.v_max)
        assert model.acceleration == pytest.approx(motion_acceleration(s.v_max, s.a_max, s.j_max, acc))
    paths = plan(problem, cfg, "downhill").paths
    fast = flight_time(problem, paths)
    assert fast == pytest.approx(flight_time(replace(problem, flight=None), paths))  # the pick decides
    assert fast < flight_time(replace(problem, pick=None), paths)  # the moderate profile flies it later


def arena() -> dict:
    """The flight-quality bench's arena: 8 robots past two pillars in 6 x 3.5 m of 0.25 m cells, v_max 1 m/s."""
    sys.path.insert(0, str(EXPERIMENTS / "bench"))
    import flight_quality as fq

    data, _ = fq.case_config("arena8")
    return data


def test_a_short_flight_s_plans_are_flown_and_the_soonest_kept():
    """The arena's flight (16 steps) is re-timed as a whole, which the flight model does not know: it puts the
    "downhill" plan sooner, and the "shared" plan flies sooner. Each plan is flown, and the run keeps the plan
    and flight of the soonest, with its metrics; the others' planning is counted in the run's timings."""
    data = apply_overrides(arena(), ["simulation.enabled=false"])
    cfg, problem = problem_of(data)
    plans = {rule: plan(problem, cfg, rule) for rule in AUTO_RULES[:2]}
    modelled = {rule: flight_time(problem, p.paths) for rule, p in plans.items()}
    assert modelled["downhill"] < modelled["shared"]  # the model alone keeps "downhill"
    auto = plan(problem, cfg)
    assert auto.contested == "downhill" and [a.contested for a in auto.alternatives] == ["shared"]
    flown = {rule: mrfswarm.plan(from_dict(apply_overrides(data, [f"mrf.contested={rule}"])), progress=False)
             for rule in plans}
    assert all(r.smoothed().retimed is not None for r in flown.values())  # the flights were re-timed
    # 5.39 s against 5.54 (5.43 against 5.71 before the leading attempt)
    assert flown["shared"].smoothed().makespan_s < 0.99 * flown["downhill"].smoothed().makespan_s
    r = mrfswarm.plan(cfg, progress=False)
    assert r.discrete.contested == "shared" and r.discrete.alternatives == ()  # dropped once compared
    assert r.smoothed().makespan_s == pytest.approx(flown["shared"].smoothed().makespan_s, rel=1e-9)
    np.testing.assert_array_equal(r.discrete.paths, plans["shared"].paths)
    np.testing.assert_array_equal(r.metrics.mean_distance, flown["shared"].metrics.mean_distance)
    assert r.metrics.final_goal_distance == flown["shared"].metrics.final_goal_distance
    assert r.timings_s["smoothing_alternatives"] > 0


def test_a_long_flight_s_plan_is_picked_by_the_model_alone():
    """A flight of more than RETIME_HORIZONS horizons is not re-timed: its alternatives are not flown."""
    data = apply_overrides(arena(), ["simulation.enabled=false", "smoothing.horizon=4"])
    cfg, problem = problem_of(data)
    r = mrfswarm.plan(cfg, progress=False)
    assert r.discrete.contested == "downhill" and r.smoothed().retimed is None
    assert "smoothing_alternatives" not in r.timings_s


def test_a_short_flight_s_plan_that_fails_to_smooth_leaves_the_others(monkeypatch):
    """Where the model's pick has no flight (its smoothing raised), a tied plan that flies is kept; where none flies,
    the run fails with the pick's error, as a run of one plan does."""
    from mrfswarm.continuous import RecedingHorizon
    from mrfswarm.errors import PlanError
    from solvers.errors import SolverError

    data = apply_overrides(arena(), ["simulation.enabled=false"])
    cfg, problem = problem_of(data)
    failing = {"downhill": plan(problem, cfg, "downhill").paths}
    run = RecedingHorizon.run

    def fails(self, on_window=None):
        if any(np.array_equal(self.paths, p) for p in failing.values()):
            raise SolverError("injected: no solution")
        return run(self, on_window)

    monkeypatch.setattr(RecedingHorizon, "run", fails)
    r = mrfswarm.plan(cfg, progress=False)
    assert r.discrete.contested == "shared" and r.continuous is not None and r.continuous.certificate.ok
    failing["shared"] = plan(problem, cfg, "shared").paths
    with pytest.raises(PlanError, match="injected"):
        mrfswarm.plan(cfg, progress=False)
