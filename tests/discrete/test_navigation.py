"""Navigation on generated maps: the geodesic goal field, per-robot outcomes, the paper's traps.

The maps and configs are ``experiments/maps/`` (written by its ``generate.py``): rooms
with 2-3-cell doorways, U/C traps facing the swarm, forests, mazes; 5-50 robots.
"""

from dataclasses import dataclass, replace
from functools import lru_cache

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mrfswarm.cli import main as cli_main
from mrfswarm.config import GoalPotentialConfig, ObstaclePotentialConfig, load_config
from mrfswarm.discrete.goal_distance import goal_distance, graph_moves
from mrfswarm.discrete.planner import SEPARATION_FACTOR, DiscretePlan, DiscreteProblem, plan_discrete
from mrfswarm.discrete.potentials import Morse, goal_distances, goal_field, obstacle_field, static_field
from mrfswarm.discrete.robot_outcomes import (
    GOAL_CELLS_PER_ROBOT,
    RobotOutcome,
    descent_ends,
    goal_region_radius,
    robot_outcomes,
)
from mrfswarm.discrete.safety import discrete_violations
from mrfswarm.errors import ConfigError, ScenarioError
from mrfswarm.maps import read_movingai
from mrfswarm.maps.synthetic import GENERATORS, generate
from mrfswarm.metrics import min_separation
from mrfswarm.pipeline import mrf_options, plan
from mrfswarm.scenario import Scenario, build_scenario
from support.fields import local_minima
from support.repository import EXPERIMENTS

MAPS = EXPERIMENTS / "maps"
MAP_CONFIGS = sorted(p.stem for p in MAPS.glob("*.toml"))
DISCRETE = ["smoothing.enabled=false"]
#: The paper's field, and its label sets (no following into a cell a robot leaves: with it the swarm of forest_03
#: files between the trees to the goal even on the straight-line field).
EUCLIDEAN = ('goal_potential.distance="euclidean"', "mrf.follow=false", "obstacle_potential.gamma=5",  # the paper's
             "mrf.trim_backward=false", "mrf.contested=downhill")  # (one plan, the rule these maps were pinned with)

#: Maps whose swarm the paper's straight-line goal field leaves short of the goal (all of them).
TRAPPED_BY_EUCLIDEAN = set(MAP_CONFIGS)


@dataclass
class MapRun:
    """The discrete stage of a map's config and every robot's outcome (what plan() reports,
    without the waypoint pruning a discrete-only plan() also does)."""

    scenario: Scenario
    discrete: DiscretePlan
    robots: list[RobotOutcome]


@lru_cache(maxsize=None)
def run_map(name: str, *overrides: str) -> MapRun:
    cfg = load_config(MAPS / f"{name}.toml", [*DISCRETE, *overrides])
    scn = build_scenario(cfg)
    d = plan_discrete(scn.discrete_problem(), method=cfg.mrf.method, max_steps=cfg.mrf.max_steps, tol=cfg.mrf.tol,
                      patience=cfg.mrf.patience, options=mrf_options(cfg), progress=cfg.mrf.progress,
                      arrival=cfg.mrf.arrival)
    robots = robot_outcomes(d.paths[-1], scn.grid.free, scn.static, cfg.mrf.order, scn.grid.resolution,
                            SEPARATION_FACTOR * scn.morse.d_min, d.stop_reason, scn.distances.path,
                            scn.goal_region_radius)
    return MapRun(scn, d, robots)


def test_map_runs_report_what_plan_reports():
    r = plan(load_config(MAPS / "trap_01.toml", [*DISCRETE, *EUCLIDEAN]), progress=False)
    m = run_map("trap_01", *EUCLIDEAN)
    assert np.array_equal(r.discrete.paths, m.discrete.paths)
    s = r.summary()
    assert [x["stop_reason"] for x in s["robots"]] == [x.stop_reason for x in m.robots]
    assert [x["at_goal"] for x in s["robots"]] == [x.at_goal for x in m.robots]


# --- the maps --------------------------------------------------------------------------------


def test_committed_maps_are_the_generators_output():
    import importlib.util

    spec = importlib.util.spec_from_file_location("generate_maps", MAPS / "generate.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    assert mod.main(["--check"]) == 0
    assert len(MAP_CONFIGS) == 4 * len(GENERATORS)
    sizes = sorted({load_config(MAPS / f"{n}.toml").scenario.start["n_robots"] for n in MAP_CONFIGS})
    assert sizes[0] == 5 and sizes[-1] == 50


@pytest.mark.parametrize("seed", range(1, 9))
def test_map_classes_have_their_shapes(seed):
    # forest: 10-20 % occupied cells inside the border
    f = generate("forest", seed)
    assert 0.10 <= f.occupied[1:-1, 1:-1].mean() <= 0.20
    # maze: corridors >= 2 cells wide (every free cell lies in a free 2 x 2 block)
    m = generate("maze", seed)
    free = ~m.occupied
    block = free[:-1, :-1] & free[1:, :-1] & free[:-1, 1:] & free[1:, 1:]
    covered = np.zeros_like(free)
    for dx in (0, 1):
        for dy in (0, 1):
            covered[dx:dx + block.shape[0], dy:dy + block.shape[1]] |= block
    assert np.array_equal(covered, free)
    # rooms: every opening in a wall line is 2 or 3 cells wide
    r = generate("rooms", seed)
    occ = r.occupied
    walls_x = [x for x in range(1, occ.shape[0] - 1) if occ[x, 1:-1].sum() > occ.shape[1] // 2]
    walls_y = [y for y in range(1, occ.shape[1] - 1) if occ[1:-1, y].sum() > occ.shape[0] // 2]
    assert walls_x or walls_y
    for line in [occ[x, :] for x in walls_x] + [occ[:, y] for y in walls_y]:
        edges = np.diff(np.r_[0, (~line).astype(int), 0])
        gaps = np.flatnonzero(edges == -1) - np.flatnonzero(edges == 1)
        assert len(gaps) and set(gaps.tolist()) <= {2, 3}, gaps
    # trap: the straight line from the start to the goal runs into the trap's wall
    t = generate("trap", seed)
    line = np.linspace(t.start, t.goal, 400).round().astype(int)
    assert t.occupied[line[:, 0], line[:, 1]].any()
    assert t.variant in {"U", "C"}
    # every class: one free region, start and goal in it
    for g in (f, m, r, t):
        d = goal_distance(~g.occupied, np.array(g.goal))
        assert np.isfinite(d.path[g.start]) and np.array_equal(d.reachable, ~g.occupied)


def test_maps_load_as_movingai_and_rotate_correctly():
    for name in MAP_CONFIGS:
        cfg = load_config(MAPS / f"{name}.toml")
        kind, seed = name.rsplit("_", 1)
        m = generate(kind, int(seed))
        grid = read_movingai(MAPS / f"{name}.map")
        assert np.array_equal(grid.occupied, m.occupied)
        assert tuple(cfg.scenario.goal) == m.goal and tuple(cfg.scenario.start["center"]) == m.start
        assert grid.is_free(np.array(m.goal)) and grid.is_free(np.array(m.start))


# --- the default reaches the goal on every map ---------------------------------------------


@pytest.mark.parametrize("name", MAP_CONFIGS)
def test_default_config_brings_every_robot_to_the_goal_and_keeps_the_swarm_together(name):
    r = run_map(name)
    assert r.scenario.config.goal_potential.distance == "geodesic"
    assert all(x.at_goal for x in r.robots), [x for x in r.robots if not x.at_goal]
    assert all(x.stop_reason is None for x in r.robots)
    d_min = r.scenario.morse.d_min
    assert max(x.nearest_neighbour for x in r.robots) <= 1.5 * d_min  # cohesive
    assert not any(x.separated for x in r.robots)
    assert r.discrete.stop_reason == "arrived"  # every robot in the goal region ends the plan
    assert min_separation(r.discrete.paths) >= 1.0 - 1e-9
    assert discrete_violations(r.discrete.paths, r.scenario.grid.free) == []


@pytest.mark.parametrize("name", MAP_CONFIGS)
def test_the_papers_straight_line_field_traps_the_swarm(name):
    """Pins the paper's behaviour on these maps: which maps leave robots short, and why."""
    r = run_map(name, *EUCLIDEAN)
    short = [x for x in r.robots if not x.at_goal]
    assert (name in TRAPPED_BY_EUCLIDEAN) == bool(short)
    assert {x.stop_reason for x in short} <= {"trapped", "stalled"}
    assert any(x.stop_reason == "trapped" for x in short)  # the field itself holds some
    assert r.discrete.stop_reason in {"trapped", "stalled"} and not r.discrete.converged
    for x in short:
        assert x.goal_distance > r.scenario.goal_region_radius


def test_a_fixed_point_short_of_the_goal_is_trapped_not_converged():
    r = run_map("trap_01", *EUCLIDEAN)  # 5 robots in a C: ICM stops moving them
    assert r.discrete.stop_reason == "trapped" and not r.discrete.converged
    assert not any(x.at_goal for x in r.robots)
    assert run_map("trap_01").discrete.stop_reason == "arrived"  # the default: the plan ends on arrival
    assert run_map("trap_01", "mrf.arrival=false").discrete.stop_reason in {"converged", "stalled"}  # at the goal


# --- the field: no local minimum but the goal ------------------------------------------------


@st.composite
def random_maps(draw):
    rng = np.random.default_rng(draw(st.integers(0, 2**31 - 1)))
    W, H = draw(st.integers(4, 22)), draw(st.integers(4, 22))
    free = rng.random((W, H)) >= draw(st.floats(0.0, 0.45))
    cells = np.argwhere(free)
    if len(cells) == 0:
        free[0, 0] = True
        cells = np.argwhere(free)
    goal = cells[rng.integers(len(cells))]
    g = GoalPotentialConfig(a=draw(st.floats(0.5, 10.0)), k=draw(st.floats(3.0, 60.0)))
    o = ObstaclePotentialConfig(gamma=draw(st.floats(0.5, 20.0)), sigma=draw(st.floats(0.0, 2.5)))
    return free, goal, g, o, draw(st.sampled_from([1, 2, 4, 5]))


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(random_maps())
def test_geodesic_static_field_has_exactly_one_local_minimum(case):
    free, goal, g, o, order = case
    prob = (~free).astype(float)
    s = static_field(prob, goal, 1.0, g, o, order)
    reach = np.isfinite(s) & free
    assert reach[tuple(goal)] and np.array_equal(np.isfinite(s), goal_distance(free, goal, 1.0, order).reachable)
    assert local_minima(reach, s, order) == [tuple(int(v) for v in goal)]
    # the goal term alone too, and steepest descent from every reachable cell ends at the goal
    d = goal_distances(prob, goal, 1.0, g, o, order)
    assert local_minima(reach, goal_field(prob.shape, goal, 1.0, g, d.field), order) == [tuple(int(v) for v in goal)]
    ends = descent_ends(free, np.where(reach, s, np.inf), order)[reach]
    assert np.all(ends == goal)
    # the margin of the proof: the next cell toward the goal is lower by >= a_G / k_G per metre
    cells = np.argwhere(reach)
    nxt = d.next_cell[cells[:, 0], cells[:, 1]]
    step = np.hypot(*(nxt - cells).T)
    drop = s[cells[:, 0], cells[:, 1]] - s[nxt[:, 0], nxt[:, 1]]
    assert np.all(drop[step > 0] >= g.a / g.k * step[step > 0] * (1 - 1e-9))
    moves = {tuple(m) for m in graph_moves(order).tolist()}
    assert {tuple(m) for m in (nxt - cells)[step > 0].tolist()} <= moves


def test_the_check_finds_the_straight_line_fields_trap():
    # the same local-minimum check on the paper's field of a trap map finds minima besides the goal
    m = generate("trap", 1)
    prob = m.occupied.astype(float)
    goal = np.array(m.goal)
    free = ~m.occupied
    s = static_field(prob, goal, 1.0, GoalPotentialConfig(distance="euclidean"), ObstaclePotentialConfig())
    minima = local_minima(free, s, 2)
    assert tuple(goal) in minima and len(minima) > 1
    assert local_minima(free, static_field(prob, goal, 1.0, GoalPotentialConfig(), ObstaclePotentialConfig()),
                        2) == [tuple(goal)]


def doorway_map() -> tuple[np.ndarray, np.ndarray]:
    """Two rooms split by a 3-cell-thick wall with a 2-cell doorway, the goal 6 m past it."""
    occ = np.zeros((30, 21), bool)
    occ[[0, -1], :] = True
    occ[:, [0, -1]] = True
    occ[14:17, :] = True
    occ[14:17, 9:11] = False
    return occ, np.array([22, 10])


@pytest.mark.parametrize("gamma, front", [(5.0, (12, 10)), (2.0, (13, 10))])  # the paper's, the default
def test_obstacle_potential_in_a_doorway_needs_the_climb_term(gamma, front):
    """Gamma blurred by sigma raises rho_O in a doorway (to 1.6 here with the paper's 5, 0.5 in front of it)
    more than the goal potential falls over the same metres near the goal (0.15-0.3 per metre): without
    counting the climb in the distance, the plain geodesic field has a local minimum in front
    of the doorway that catches the whole far room (with Gamma 2 as well)."""
    occ, goal = doorway_map()
    free = ~occ
    obstacle = ObstaclePotentialConfig(gamma=gamma)
    rho_o = obstacle_field(occ.astype(float), obstacle)
    g = GoalPotentialConfig()
    plain = goal_distance(free, goal, 1.0, 2, rho_o, climb_weight=0.0)
    s_plain = np.where(free, goal_field(occ.shape, goal, 1.0, g, plain.field) + rho_o, np.inf)
    minima = local_minima(free, s_plain, 2)
    assert tuple(goal) in minima and front in minima  # just in front of the doorway
    caught = (descent_ends(free, s_plain, 2)[free] != goal).any(axis=1).sum()
    assert caught > 200
    s = static_field(occ.astype(float), goal, 1.0, g, obstacle)
    assert local_minima(free, s, 2) == [tuple(goal)]
    assert np.all(np.isfinite(s[free]))


def test_geodesic_distance_is_the_path_length_in_open_space():
    free = np.ones((25, 25), bool)
    d = goal_distance(free, np.array([12, 12]), resolution=0.5)
    x, y = np.meshgrid(np.arange(25) - 12, np.arange(25) - 12, indexing="ij")
    octile = (np.maximum(abs(x), abs(y)) + (np.sqrt(2) - 1) * np.minimum(abs(x), abs(y))) * 0.5
    np.testing.assert_allclose(d.path, octile, atol=1e-12)
    assert np.all(d.path >= np.hypot(x, y) * 0.5 - 1e-12) and np.all(d.path <= np.hypot(x, y) * 0.5 * 1.0824 + 1e-12)
    np.testing.assert_array_equal(d.field, d.path)  # no climb weight: the same
    four = goal_distance(free, np.array([12, 12]), order=1)
    np.testing.assert_allclose(four.path, abs(x) + abs(y))


def test_diagonal_moves_do_not_cut_corners_in_the_search():
    # free cells (0,0) and (1,1) touch only at a corner: 8-connected but not joined for a robot
    free = np.array([[True, False, True], [False, True, True], [True, True, True]])
    d = goal_distance(free, np.array([1, 1]))
    assert np.isinf(d.path[0, 0]) and d.path[0, 2] == 2.0 and d.path[2, 0] == 2.0


def test_goal_distance_rejects_bad_input():
    free = np.ones((4, 4), bool)
    free[3, 3] = False
    with pytest.raises(ValueError, match="not a free cell"):
        goal_distance(free, np.array([3, 3]))
    with pytest.raises(ValueError, match="not a free cell"):
        goal_distance(free, np.array([5, 0]))
    with pytest.raises(ValueError, match="climb_weight"):
        goal_distance(free, np.array([0, 0]), climb_weight=-1.0)
    with pytest.raises(ValueError, match="obstacle potential"):
        goal_distance(free, np.array([0, 0]), climb_weight=1.0)
    with pytest.raises(TypeError, match=r"goal cell \[2.5, 1.0\] must be integer cell indices"):
        goal_distance(free, np.array([2.5, 1.0]))  # was searched from cell (2, 1)


def test_a_goal_too_far_for_k_is_a_clear_error(tmp_path):
    cfg = tmp_path / "c.toml"
    cfg.write_text('[scenario]\nmap = { kind = "free", size = [60, 5] }\nstart = { positions = [[1, 2], [2, 2]] }\n'
                   "goal = [58, 2]\n[interaction]\nk = 1\n[goal_potential]\nk = 0.05\n")
    with pytest.raises(ScenarioError, match=r"goal_potential.k = 0.05 cells is too small .* use k >= 0\.084"):
        plan(load_config(cfg, DISCRETE))
    # k counts cells: the same map at 0.25 m cells (goal 14.25 m away) needs the same k
    fine = ['scenario.map = { kind = "free", size = [60, 5], resolution = 0.25 }',
            "scenario.start = { positions = [[0.25, 0.5], [0.5, 0.5]] }", "scenario.goal = [14.5, 0.5]"]
    with pytest.raises(ScenarioError, match=r"lie 59 cells from the goal .* use k >= 0\.084"):
        plan(load_config(cfg, DISCRETE + fine))


# --- unreachable robots and goals --------------------------------------------------------------

POCKET = ('map = { kind = "ascii", rows = ["..........", ".###......", ".#.#......", ".###......", ".........."] }\n')


def test_a_robot_without_a_path_to_the_goal_is_named(tmp_path):
    cfg = tmp_path / "c.toml"
    cfg.write_text(f"[scenario]\n{POCKET}start = {{ positions = [[2, 2], [5, 0], [6, 1]] }}\ngoal = [9, 4]\n"
                   "[interaction]\nk = 1\n")
    with pytest.raises(ScenarioError, match=r"no free path to the goal \(9, 4\) from robot 0 at \(2, 2\); move it "):
        plan(load_config(cfg, DISCRETE))
    # the paper's field plans anyway and says which robot could not get there
    r = plan(load_config(cfg, [*DISCRETE, *EUCLIDEAN]), progress=False)
    robots = r.summary()["robots"]
    assert robots[0]["stop_reason"] == "unreachable" and robots[0]["goal_distance_m"] is None
    assert robots[1]["at_goal"] and robots[2]["at_goal"]


def test_a_goal_no_robot_can_reach_is_a_clear_error(tmp_path, capsys):
    cfg = tmp_path / "c.toml"
    cfg.write_text(f"[scenario]\n{POCKET}start = {{ positions = [[5, 0], [6, 1]] }}\ngoal = [2, 2]\n"
                   "[interaction]\nk = 1\n")
    rc = cli_main(["run", str(cfg), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "scenario.goal (2, 2) cannot be reached: no robot has a free path" in err[0]


def test_the_discrete_stage_refuses_a_start_with_an_infinite_field():
    free = np.ones((6, 6), bool)
    free[3, :] = False
    goal = np.array([5, 5])
    static = static_field((~free).astype(float), goal, 1.0, GoalPotentialConfig(), ObstaclePotentialConfig())
    problem = DiscreteProblem(free=free, static=static, start=np.array([[0, 0], [4, 4]]), goal=goal, morse=Morse(),
                              k=1)
    with pytest.raises(ScenarioError, match=r"robot 0 at cell \(0, 0\) has no free path"):
        plan_discrete(problem)


# --- per-robot outcomes ------------------------------------------------------------------------


def test_the_robot_left_behind_is_reported():
    """The paper's Fig. 4 map with the paper's field: four robots at the goal, one left behind a
    block, 21 m from the others (what 'converged' used to hide); the default field brings it."""
    r = plan(load_config(EXPERIMENTS / "combined_field.toml", DISCRETE), progress=False)
    s = r.summary()
    assert s["stop_reason"] == "trapped" and not s["converged"] and not s["reached_goal"]
    left = [x for x in s["robots"] if not x["at_goal"]]
    assert [x["robot"] for x in left] == [4]
    assert left[0]["stop_reason"] == "trapped" and left[0]["separated"]
    assert left[0]["nearest_neighbour_m"] > SEPARATION_FACTOR * r.scenario.morse.d_min
    assert s["robots_separated"] == 1 and s["steps_with_separated_robots"] > 0
    assert s["robots"][4]["final"] == [42.0, 15.0]
    geo = plan(load_config(EXPERIMENTS / "combined_field.toml",
                           [*DISCRETE, 'goal_potential.distance="geodesic"']), progress=False).summary()
    assert geo["robots_at_goal"] == 5 and geo["robots_separated"] == 0


def test_goal_region_holds_four_cells_per_robot():
    free_path = goal_distance(np.ones((40, 40), bool), np.array([20, 20])).path
    r = goal_region_radius(free_path, 25, 3.0)
    assert (free_path <= r - 3.0).sum() >= GOAL_CELLS_PER_ROBOT * 25 > (free_path < r - 3.0).sum()
    # in a 2-cell corridor the region stretches along it
    corridor = np.zeros((60, 2), bool) | True
    cp = goal_distance(corridor, np.array([0, 0])).path
    assert goal_region_radius(cp, 25, 3.0) == pytest.approx(3.0 + 48 + np.sqrt(2))  # 100th cell: (49, 1)


def test_stalled_robots_are_told_from_trapped_ones():
    # with patience on the swarm energy only, a 50-robot swarm stops while still filing in:
    # the robots left behind are held by the robots ahead, not by the field
    # (with the paper's label sets and end rule: following into the cells robots leave, or ending the plan on
    # arrival, the defaults, let this swarm arrive)
    r = run_map("trap_04", 'mrf.progress="energy"', "mrf.follow=false", "mrf.arrival=false", "mrf.contested=downhill")
    short = [x for x in r.robots if not x.at_goal]
    assert short and {x.stop_reason for x in short} == {"stalled"}
    assert r.discrete.stop_reason == "stalled"


def test_trimmed_robots_stuck_in_their_cell_get_their_moves_back():
    """Trimming every move that lengthens the way to the goal (``mrf.trim_slack = 0``) takes from a crowd the
    sideways moves that make room: 50 robots in rooms_01 (start seed 1) leave one robot stalled behind the
    others. Either guard brings it home: ``mrf.trim_escape`` (default 2: a robot that has stayed in its cell for
    two steps gets its whole label set back), or the default slack (sideways moves kept)."""
    # congestion 5, the default before the twenty-fourth session: at 8 the robot is not left behind either way;
    # the contested rule "auto" kept then ("shared"; "downhill" leaves it behind too, "queue" does not)
    start = ("scenario.start.n_robots=50", "scenario.start.seed=1", "mrf.trim_backward=true",
             "goal_potential.congestion=5", "mrf.contested=shared")
    never = run_map("rooms_01", *start, "mrf.trim_escape=0", "mrf.trim_slack=0")
    assert [x.stop_reason for x in never.robots if not x.at_goal] == ["stalled"]
    assert never.discrete.stop_reason == "trapped"
    for guard in (("mrf.trim_slack=0",), ("mrf.trim_escape=0",)):
        escaped = run_map("rooms_01", *start, *guard)
        assert all(x.at_goal for x in escaped.robots) and escaped.discrete.stop_reason == "arrived", guard
        assert discrete_violations(escaped.discrete.paths, escaped.scenario.grid.free) == []


def test_the_trim_is_lifted_only_for_robots_that_stayed():
    from mrfswarm.discrete.label_sets import label_sets
    from mrfswarm.discrete.planner import trim_mask

    problem = DiscreteProblem(free=np.ones((12, 12), bool), static=np.zeros((12, 12)), start=np.zeros((3, 2), int),
                              goal=np.array([11, 5]), morse=Morse(0.7, 0.9, 14.0, 4.0), trim_backward=True,
                              trim_escape=2)
    moving = [np.array([[0, 0], [4, 4], [8, 8]]) + [t, 0] * np.array([[1], [0], [1]]) for t in range(3)]
    assert trim_mask(problem, moving[:2]) is None  # not two steps yet
    assert trim_mask(problem, moving).tolist() == [True, False, True]  # robot 1 stayed two steps
    assert trim_mask(replace(problem, trim_escape=0), moving) is None
    assert trim_mask(replace(problem, trim_backward=False), moving) is None
    cells = np.array([[2, 2], [2, 8]])
    away = np.array([-1, 0])  # a move west, away from the goal in the east
    for trim, kept in (([True, True], [False, False]), ([True, False], [False, True]), (False, [True, True])):
        ls = label_sets(np.ones((12, 12), bool), cells, 2, np.array([11, 5]), np.array(trim) if trim else trim)
        offsets = ls.offsets  # (N, L, d), padded with the stay
        assert [bool(np.any(np.all(offsets[i] == away, axis=-1))) for i in range(2)] == kept


def test_the_trim_slack_keeps_the_sideways_moves_of_the_papers_rule():
    """In open space the free-path distance is measured over 8 directions, so a move square to the way raises
    it by 0.41 cell (straight way) or 0.59 (diagonal way): the default slack, half a cell, keeps the sideways
    moves of a straight way, which the paper's dot-product rule keeps, and 0 drops them; every move that
    raises the distance by a cell or more is trimmed either way."""
    from mrfswarm.discrete.label_sets import label_sets

    free = np.ones((21, 21), bool)
    goal = np.array([18, 10])
    d = goal_distances(np.zeros(free.shape), goal, 1.0, GoalPotentialConfig(), ObstaclePotentialConfig())
    cell = np.array([[6, 10]])  # west of the goal: the way is east

    def kept(slack: float) -> set[tuple[int, ...]]:
        ls = label_sets(free, cell, 2, goal, True, goal_distance=d.field, trim_slack=slack)
        return {tuple(o) for o in ls.offsets[0, :ls.count[0]].tolist()}

    forward = {(0, 0), (1, -1), (1, 0), (1, 1)}
    assert kept(0.0) == forward
    assert kept(0.5) == forward | {(0, -1), (0, 1)}
    assert kept(0.5) == {tuple(o) for o in label_sets(free, cell, 2, goal, True).offsets[0].tolist()}  # the paper's
    assert kept(0.99) == kept(0.5)  # back and back-diagonal moves raise it by >= 1


# --- config -------------------------------------------------------------------------------------


@pytest.mark.parametrize("key, value, match", [
    ("goal_potential.distance", '"manhattan"', "must be one of geodesic, euclidean"),
    ("mrf.contested", '"random"', "must be one of auto, shared, queue, downhill, nearest"),
    ("mrf.progress", '"never"', "must be one of static, energy"),
    ("mrf.trim_escape", "-1", "must be >= 0"),
    ("mrf.trim_slack", "-0.5", "must be >= 0"),
])
def test_new_config_keys_are_checked(key, value, match):
    with pytest.raises(ConfigError, match=match):
        load_config(None, [f"{key}={value}"])


def test_defaults_navigate_and_paper_configs_pin_the_papers_rules():
    cfg = load_config(None)
    assert (cfg.goal_potential.distance, cfg.mrf.contested, cfg.mrf.progress) == ("geodesic", "auto", "static")
    assert cfg.mrf.follow and cfg.mrf.arrival and cfg.obstacle_potential.gamma == 2.0
    assert cfg.mrf.trim_backward and cfg.mrf.trim_escape == 2 and cfg.mrf.trim_slack == 0.5
    for name in ("corridor", "blocks", "corridor10", "blocks12", "free5", "free10", "example5", "single_obstacle",
                 "combined_field", "swarm_size"):
        c = load_config(EXPERIMENTS / f"{name}.toml")
        assert (c.goal_potential.distance, c.mrf.contested, c.mrf.progress) == ("euclidean", "nearest", "energy")
        assert not c.mrf.follow and not c.mrf.arrival
        assert c.obstacle_potential.gamma == 5.0  # the paper's table
        assert not c.mrf.trim_backward


def test_trim_backward_follows_the_free_path_with_the_geodesic_field():
    """Trimming by the straight direction to the goal cuts the way around a wall; with the
    geodesic field the trim drops the moves that lengthen the way along free paths instead."""
    from mrfswarm.discrete.label_sets import label_sets

    m = generate("trap", 1)
    free = ~m.occupied
    goal = np.array(m.goal)
    d = goal_distances(m.occupied.astype(float), goal, 1.0, GoalPotentialConfig(), ObstaclePotentialConfig())
    cells = np.argwhere(free & (d.path > 0))
    for order in (1, 2, 4):
        paper = label_sets(free, cells, order, goal, trim_backward=True)
        geo = label_sets(free, cells, order, goal, trim_backward=True, goal_distance=d.field)
        after = geo.cells[np.arange(len(cells))[:, None], np.arange(geo.index.shape[1])[None]]
        here = d.field[cells[:, 0], cells[:, 1]][:, None]
        assert np.all(~geo.valid | (d.field[after[..., 0], after[..., 1]] <= here))
        # one robot alone keeps its move toward the goal; the straight-line trim loses it somewhere
        lone = [label_sets(free, c[None], order, goal, trim_backward=True, goal_distance=d.field) for c in cells[::37]]
        nxt = d.next_cell[cells[::37, 0], cells[::37, 1]]
        if order >= 2:
            assert all(any((ls.cells[0, :ls.count[0]] == n).all(1)) for ls, n in zip(lone, nxt))
        kept_paper = [any((paper.cells[i, :paper.count[i]] == n).all(1))
                      for i, n in zip(range(len(cells)), d.next_cell[cells[:, 0], cells[:, 1]])]
        assert not all(kept_paper)


def test_trim_backward_still_gets_the_swarm_around_a_trap():
    r = run_map("trap_02", "mrf.trim_backward=true")
    assert all(x.at_goal for x in r.robots)
