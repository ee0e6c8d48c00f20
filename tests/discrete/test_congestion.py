"""The goal field priced for the swarm's own jams (``goal_potential.congestion``)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mrfswarm.config import CONGESTION, GoalPotentialConfig, ObstaclePotentialConfig, from_dict
from mrfswarm.discrete.congestion import CongestionField
from mrfswarm.discrete.goal_distance import GoalGraph, goal_distance
from mrfswarm.discrete.potentials import obstacle_field, static_field
from mrfswarm.discrete.safety import discrete_violations
from mrfswarm.errors import ConfigError
from mrfswarm.pipeline import plan
from support.fields import local_minima


def _rows(occ: np.ndarray) -> list[str]:
    W, H = occ.shape
    return ["".join("@" if occ[x, y] else "." for x in range(W)) for y in range(H)]


def field_of(free: np.ndarray, goal: np.ndarray, weight: float = CONGESTION, order: int = 2,
             g: GoalPotentialConfig | None = None, o: ObstaclePotentialConfig | None = None,
             region: float = 0.0) -> CongestionField:
    g, o = g or GoalPotentialConfig(), o or ObstaclePotentialConfig()
    prob = (~free).astype(float)
    obstacle = obstacle_field(prob, o)
    graph = GoalGraph.build(free, goal, 1.0, order, obstacle, climb_weight=g.k / g.a)
    return CongestionField(graph=graph, obstacle=obstacle, goal_cfg=g, resolution=1.0, weight=weight, every=5,
                           goal_path=goal_distance(free, goal, 1.0, order).path, region_radius=region)


def two_gaps() -> np.ndarray:
    """A 40 x 30 map cut by a wall at x = 20 with a 1-cell gap on the straight line (y = 15) and a
    3-cell gap 10 cells off it (y = 3..5)."""
    occ = np.zeros((40, 30), dtype=bool)
    occ[20, :] = True
    occ[20, 15] = False
    occ[20, 3:6] = False
    return ~occ


def test_without_stalled_robots_the_field_is_the_static_one():
    free, goal = two_gaps(), np.array([32, 15])
    cf = field_of(free, goal)
    static, dist = cf.fields(np.zeros((0, 2), dtype=int))
    g, o = GoalPotentialConfig(), ObstaclePotentialConfig()
    np.testing.assert_allclose(static, static_field((~free).astype(float), goal, 1.0, g, o), rtol=1e-12)
    assert np.isinf(dist[~free]).all()


def test_robots_behind_a_jam_take_the_other_gap():
    free, goal = two_gaps(), np.array([32, 15])
    cf = field_of(free, goal)
    jam = np.array([[x, y] for x in range(16, 20) for y in range(13, 18)])  # packed in front of the 1-cell gap
    behind = (10, 15)

    def gap_taken(dist: np.ndarray) -> str:
        """Follow the steepest descent of ``dist`` from ``behind`` to the wall."""
        p = np.array(behind)
        while p[0] < 20:
            nbr = [p + d for d in np.array([[i, j] for i in (-1, 0, 1) for j in (-1, 0, 1) if i or j])
                   if free[tuple(p + d)]]
            p = min(nbr, key=lambda q: dist[tuple(q)])
        return "narrow" if p[1] == 15 else "wide"

    assert gap_taken(cf.fields(np.zeros((0, 2), dtype=int))[1]) == "narrow"  # the static field: the short way
    assert gap_taken(cf.fields(jam)[1]) == "wide"  # priced in, the jam is longer than the detour
    assert gap_taken(field_of(free, goal, weight=0.0).fields(jam)[1]) == "narrow"  # weight 0: no pricing


def test_only_robots_that_stayed_outside_the_goal_region_count():
    free, goal = two_gaps(), np.array([32, 15])
    cf = field_of(free, goal, region=3.0)
    before = np.array([[5, 5], [6, 8], [32, 14], [10, 10]])
    after = np.array([[5, 5], [7, 8], [32, 14], [10, 10]])
    # robot 1 moved, robot 2 stayed inside the goal region
    np.testing.assert_array_equal(cf.stalled(before, after), [True, False, False, True])


@st.composite
def jammed_maps(draw):
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    W, H = draw(st.integers(6, 18)), draw(st.integers(6, 18))
    free = rng.random((W, H)) > draw(st.floats(0.0, 0.35))
    cells = np.argwhere(free)
    if len(cells) < 2:
        free[:2, 0] = True
        cells = np.argwhere(free)
    goal = cells[rng.integers(len(cells))]
    stalled = cells[rng.random(len(cells)) < draw(st.floats(0.0, 0.6))]
    g = GoalPotentialConfig(a=draw(st.floats(0.5, 10.0)), k=draw(st.floats(3.0, 60.0)))
    o = ObstaclePotentialConfig(gamma=draw(st.floats(0.5, 20.0)), sigma=draw(st.floats(0.0, 2.5)))
    return free, goal, stalled, g, o, draw(st.floats(0.0, 20.0)), draw(st.sampled_from([1, 2, 4]))


@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(jammed_maps())
def test_a_congested_field_keeps_one_local_minimum_the_goal(case):
    """The static field's guarantee holds for any jam: moves cost at least their length."""
    free, goal, stalled, g, o, w, order = case
    static, dist = field_of(free, goal, w, order, g, o).fields(stalled)
    reach = goal_distance(free, goal, 1.0, order).reachable
    assert np.array_equal(np.isfinite(dist), reach)
    assert local_minima(reach, static, order) == [tuple(int(v) for v in goal)]
    assert np.all(dist[reach] >= goal_distance(free, goal, 1.0, order).path[reach] - 1e-9)  # never shorter


def _gap_config(weight: float | None, n: int = 30) -> dict:
    scn = {"map": {"kind": "ascii", "rows": _rows(~two_gaps())},
           "start": {"center": [8, 15], "n_robots": n, "sigma": 2.0, "seed": 0}, "goal": [32, 15]}
    gp = {} if weight is None else {"congestion": weight}
    return {"scenario": scn, "interaction": {"k": 7}, "goal_potential": gp, "smoothing": {"enabled": False},
            "simulation": {"enabled": False}}


def test_a_swarm_queueing_at_a_gap_spreads_to_the_other_and_arrives_sooner():
    runs = {w: plan(from_dict(_gap_config(w), Path(".")), progress=False) for w in (0.0, None)}
    off, on = runs[0.0].discrete, runs[None].discrete  # None: the default weight
    for d in (off, on):
        assert d.stop_reason == "arrived"
        assert discrete_violations(d.paths, two_gaps()) == []

    def wide(paths: np.ndarray) -> int:
        return int(np.any((paths[..., 0] == 20) & (paths[..., 1] < 10), axis=0).sum())

    assert off.congested_fields == 0 and on.congested_fields > 0
    assert wide(on.paths) > wide(off.paths) + 3  # measured: 12 robots against 0 (w 5: 6)
    assert on.n_steps < 0.93 * off.n_steps  # measured: 36 steps against 52 (w 5: 42)


def test_congestion_config_is_validated():
    assert GoalPotentialConfig().congestion_weight == CONGESTION
    assert GoalPotentialConfig(distance="euclidean").congestion_weight == 0.0
    assert GoalPotentialConfig(congestion=0.0).congestion_weight == 0.0
    base = _gap_config(None)
    for table, needle in [({"congestion": -1.0}, "goal_potential.congestion = -1.0"),
                          ({"congestion": float("nan")}, "goal_potential.congestion must be finite"),
                          ({"congestion": 2.0, "distance": "euclidean"}, "needs goal_potential.distance"),
                          ({"congestion_every": 0}, "goal_potential.congestion_every = 0")]:
        with pytest.raises(ConfigError, match=needle):
            from_dict({**base, "goal_potential": table}, Path("."))
    # the euclidean field with the default (unset) weight is fine: congestion is off there
    from_dict({**base, "goal_potential": {"distance": "euclidean"}}, Path("."))


def test_a_congested_field_that_would_overflow_is_not_used(caplog):
    free = np.ones((120, 3), dtype=bool)
    goal = np.array([119, 1])
    g = GoalPotentialConfig(k=0.2)  # the static field reaches 119 / 0.2 = 595 < 700: fine
    cf = field_of(free, goal, 20.0, g=g)
    assert np.isfinite(cf.fields(np.zeros((0, 2), dtype=int))[0][free]).all()
    jam = np.array([[x, 1] for x in range(0, 110, 2)])  # priced in, the far end is > 700 k away
    with caplog.at_level("WARNING"):
        assert cf.fields(jam) is None
    assert "overflows" in caplog.text


def test_the_scenario_s_congestion_searches_the_geodesic_field_s_graph():
    """The congestion's graph is the one the geodesic goal field was searched on (built a second time before: 5.6 s
    on a 2000 x 2000 map), and a congested field is the same as with a graph built again."""
    from mrfswarm.scenario import build_scenario

    free, goal = two_gaps(), np.array([32, 15])
    cfg = from_dict({"scenario": {"map": {"kind": "ascii", "rows": _rows(~free)}, "goal": goal.tolist(),
                                  "start": {"positions": [[5, 15], [5, 13]]}},
                     "goal_potential": {"congestion": CONGESTION}})
    scn = build_scenario(cfg)
    cf = scn.congestion_field()
    assert cf.graph is scn.distances.graph
    g, o = cfg.goal_potential, cfg.obstacle_potential
    fresh = GoalGraph.build(free, goal, 1.0, cfg.mrf.order, obstacle_field((~free).astype(float), o),
                            climb_weight=g.k / g.a)
    np.testing.assert_array_equal(cf.graph.climb, fresh.climb)
    jam = np.array([[x, y] for x in range(16, 20) for y in range(13, 18)])
    again = CongestionField(graph=fresh, obstacle=cf.obstacle, goal_cfg=g, resolution=1.0, weight=cf.weight,
                            every=cf.every, goal_path=cf.goal_path, region_radius=cf.region_radius)
    for a, b in zip(cf.fields(jam), again.fields(jam)):
        np.testing.assert_array_equal(a, b)
    off = build_scenario(cfg.replace(goal_potential=dataclasses.replace(cfg.goal_potential, congestion=0.0)))
    assert off.congestion_field() is None and off.distances.graph is None  # not kept where nothing searches it
