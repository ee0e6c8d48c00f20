"""The discrete stage on voxels (d = 3) with downwash, against brute force.

Stencil, swept voxels, label sets, hard conflicts in the downwash-scaled metric, the
goal field, the interaction graph, the safety checks (each fed the violation it exists
for), pruning, and a whole plan through a window in a wall.
"""

import itertools
import tracemalloc

import networkx as nx
import numpy as np
import pytest
from scipy.spatial import cKDTree

from mrfswarm.config import GoalPotentialConfig, ObstaclePotentialConfig, from_dict
from mrfswarm.discrete.goal_distance import goal_distance, graph_moves
from mrfswarm.discrete.interaction_graph import knn_edges, maximal_cliques
from mrfswarm.discrete.label_sets import LabelSets, label_sets, shadow_offsets
from mrfswarm.discrete.motion import moves_clear, segments_clear, stencil, step_min_separation, swept_cells
from mrfswarm.discrete.planner import DiscreteProblem, plan_discrete
from mrfswarm.discrete.potentials import Morse, goal_distances, static_field
from mrfswarm.discrete.pruning import prune_paths, prune_paths_brute_force
from mrfswarm.discrete.robot_outcomes import descent_ends, goal_region_radius
from mrfswarm.discrete.safety import discrete_violations, discrete_violations_brute_force
from mrfswarm.discrete.step_mrf import collision_table, conflict_tables
from mrfswarm.errors import ConfigError, ScenarioError
from mrfswarm.geometry import downwash_scale, segment_clear
from mrfswarm.scenario import build_scenario

SAMPLES = 1001


def scaled_norm(v, c):
    return np.linalg.norm(np.asarray(v, float) * downwash_scale(3, c), axis=-1)


# ------------------------------------------------------------------ stencil and motion


@pytest.mark.parametrize("n, size", [(1, 7), (2, 19), (3, 27), (4, 33), (5, 57)])
def test_stencil_in_3d(n, size):
    s = stencil(n, 3)
    assert s.shape == (size, 3) and s[0].tolist() == [0, 0, 0]
    d2 = (s**2).sum(1)
    assert np.all(d2 <= n) and np.all(np.diff(d2) >= 0) and len(np.unique(s, axis=0)) == size
    brute = {o for o in itertools.product(range(-3, 4), repeat=3) if sum(v * v for v in o) <= n}
    assert {tuple(o) for o in s.tolist()} == brute


def test_the_planar_stencil_is_unchanged():
    # by length, then angle from -pi: the label order of every 2-D plan
    assert stencil(2).tolist() == [[0, 0], [0, -1], [1, 0], [0, 1], [-1, 0], [-1, -1], [1, -1], [1, 1], [-1, 1]]
    assert np.array_equal(stencil(2, 2), stencil(2))


def test_swept_voxels_by_brute_force():
    # a voxel is required iff its cube comes closer than half a cell to the move's segment
    grid = np.array(list(itertools.product(range(-3, 4), repeat=3)), float)
    pts_s = np.linspace(0, 1, SAMPLES)[:, None]
    for n in (1, 2, 3, 4):
        cells, count = swept_cells(n, 3)
        for s, o in enumerate(stencil(n, 3)):
            req = {tuple(c) for c in cells[s, : count[s]].tolist()}
            pts = pts_s * o  # (P, 3)
            g = np.maximum(0, np.abs(pts[:, None, :] - grid[None]) - 0.5)  # (P, G, 3)
            d = np.linalg.norm(g, axis=-1).min(axis=0)
            for c, dc in zip(grid.astype(int).tolist(), d):
                if abs(dc - 0.5) > 1e-3:
                    assert (tuple(c) in req) == (dc < 0.5), (n, o, c, dc)


def test_moves_clear_agrees_with_segment_clear_in_3d():
    rng = np.random.default_rng(3)
    free = rng.random((6, 6, 5)) > 0.3
    starts = np.argwhere(free)
    for n in (1, 3, 4):
        S = len(stencil(n, 3))
        ok = moves_clear(free, starts, np.broadcast_to(np.arange(S), (len(starts), S)), n)
        for i in range(0, len(starts), 9):
            ends = starts[i] + stencil(n, 3)
            assert np.array_equal(segments_clear(free, np.repeat(starts[i:i + 1], S, 0), ends), ok[i])
            for s, o in enumerate(stencil(n, 3)):
                assert ok[i, s] == segment_clear(free, starts[i], starts[i] + o), (starts[i], o)


def test_no_edge_or_corner_cutting_in_3d():
    free = np.ones((3, 3, 3), bool)
    free[1, 0, 0] = False
    moves = {tuple(o): k for k, o in enumerate(stencil(3, 3).tolist())}
    ok = moves_clear(free, np.array([[0, 0, 0]]), np.arange(27)[None], 3)[0]
    assert not ok[moves[(1, 1, 0)]] and not ok[moves[(1, 0, 1)]] and not ok[moves[(1, 1, 1)]]
    assert ok[moves[(0, 1, 1)]] and ok[moves[(0, 1, 0)]] and ok[moves[(0, 0, 1)]]


# ------------------------------------------------------------------ label sets


def check_label_sets(ls, free, starts, order, downwash, follow=False):
    assert np.all(ls.index[:, 0] == 0) and np.all(ls.count >= 1)
    owner = {}
    others = {tuple(c) for c in starts.tolist()}
    for i in range(len(starts)):
        for l in range(ls.count[i]):
            c = tuple(ls.cells[i, l].tolist())
            if follow and l == 0:  # an occupant's stay may also be one other robot's label
                continue
            assert c not in owner, "X_i and X_j must be disjoint"
            owner[c] = i
            assert free[c]
            if l > 0:
                o = ls.offsets[i, l]
                assert (o**2).sum() <= order
                assert segment_clear(free, starts[i], starts[i] + o)
                if not follow:
                    # no label closer than one cell (scaled) to another robot, nor on one's own cell
                    near = [j for j in range(len(starts)) if j != i
                            and scaled_norm(np.array(c) - starts[j], downwash) < 1 - 1e-9]
                    assert c not in others and not near, (i, c, near)
    # rule (b) in the scaled metric: no two moves of different robots end closer than one cell
    moves = [(i, ls.cells[i, l]) for i in range(len(starts)) for l in range(1, ls.count[i])]
    for (i, a), (j, b) in itertools.combinations(moves, 2):
        if i != j:
            assert scaled_norm(a - b, downwash) >= 1 - 1e-9, (i, a, j, b)


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("order", [1, 2, 3])
@pytest.mark.parametrize("downwash", [1.0, 2.0, 3.0])
def test_label_set_rules_in_3d(seed, order, downwash):
    rng = np.random.default_rng(seed)
    free = rng.random((8, 8, 6)) > 0.2
    cells = np.argwhere(free)
    rng.shuffle(cells)
    starts = cells[:30]
    static = rng.normal(size=free.shape)
    for follow in (False, True):
        ls = label_sets(free, starts, order, static=static, contested="downhill", follow=follow, downwash=downwash)
        assert ls.ndim == 3 and ls.cells.shape[2] == 3
        check_label_sets(ls, free, starts, order, downwash, follow)


def test_shadow_offsets():
    assert shadow_offsets(2, 3.0).shape == (0, 2)
    assert shadow_offsets(3, 1.0).shape == (0, 3)
    assert shadow_offsets(3, 2.0).tolist() == [[0, 0, -1], [0, 0, 1]]
    assert sorted(shadow_offsets(3, 2.5)[:, 2].tolist()) == [-2, -1, 1, 2]


def test_the_shadow_rule_fires():
    free = np.ones((5, 5, 6), bool)
    starts = np.array([[2, 2, 1], [2, 2, 3]])  # 2 apart in z: apart for c = 2
    up = next(k for k, o in enumerate(stencil(2, 3).tolist()) if o == [0, 0, 1])
    with_c1 = label_sets(free, starts, 2, downwash=1.0)
    with_c2 = label_sets(free, starts, 2, downwash=2.0)
    assert up in with_c1.index[0, : with_c1.count[0]]  # (2, 2, 2): one voxel under robot 1, fine with c = 1
    assert up not in with_c2.index[0, : with_c2.count[0]]  # its downwash shadow with c = 2


# ------------------------------------------------------------------ hard conflicts


def brute_conflicts(ls, i, j, c):
    s = np.linspace(0, 1, SAMPLES)[:, None, None, None]
    d0 = (ls.starts[i] - ls.starts[j]).astype(float)
    v = (ls.offsets[i][:, None, :] - ls.offsets[j][None, :, :]).astype(float)
    dist = scaled_norm(d0 + s * v, c).min(axis=0)
    return (dist < 1 - 1e-6) & ls.valid[i][:, None] & ls.valid[j][None, :]


@pytest.mark.parametrize("order", [1, 2, 3])
@pytest.mark.parametrize("downwash", [1.0, 2.0, 3.0])
def test_conflicts_match_brute_force_in_3d(order, downwash):
    rng = np.random.default_rng(order)
    S = len(stencil(order, 3))
    # packed robots with full, overlapping stencils: many real conflicts
    cells = np.array(list(itertools.product(range(3, 6), range(3, 6), range(2, 9, 2))))
    starts = cells[rng.choice(len(cells), 7, replace=False)]
    ls = LabelSets(index=np.tile(np.arange(S), (len(starts), 1)), count=np.full(len(starts), S), starts=starts,
                   order=order)
    pairs, mask = conflict_tables(ls, downwash)
    table = {tuple(p): m for p, m in zip(pairs.tolist(), mask)}
    found = 0
    for i in range(len(starts)):
        for j in range(i + 1, len(starts)):
            expect = brute_conflicts(ls, i, j, downwash)
            got = table.get((i, j), np.zeros_like(expect))
            np.testing.assert_array_equal(got, expect, err_msg=f"robots {i}, {j}")
            found += int(expect.sum())
    assert found > 0


def test_moving_under_a_robot_is_a_conflict_with_downwash():
    # robot 0 slides under robot 1 (one voxel above its path): fine with c = 1, forbidden with c = 2
    S = len(stencil(2, 3))
    starts = np.array([[0, 0, 0], [1, 0, 1]])
    ls = LabelSets(index=np.tile(np.arange(S), (2, 1)), count=np.full(2, S), starts=starts, order=2)
    a = next(k for k, o in enumerate(stencil(2, 3).tolist()) if o == [1, 0, 0])
    for c, conflict in ((1.0, False), (2.0, True)):
        pairs, mask = conflict_tables(ls, c)
        m = dict(zip(map(tuple, pairs.tolist()), mask))
        assert bool(m.get((0, 1), np.zeros((S, S), bool))[a, 0]) is conflict, c
    table, R = collision_table(2, 3, 2.0)
    assert R.tolist() == [3, 3, 7]  # offsets up to c x the radius in z


def test_the_collision_table_takes_little_more_memory_than_itself():
    """Each distinct relative move's distance once, in chunks of start offsets. All (offset, move, move) distances
    at once took 56 times the table at order 8 on voxels, 24 GB at order 16 (killed; stress tour)."""
    tracemalloc.start()
    try:
        table, _ = collision_table.__wrapped__(8, 3, 1.0)  # not the cached one
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 2 * table.nbytes


@pytest.mark.parametrize("order, downwash, fits", [(32, 1.0, 20), (16, 3.0, 15)])
def test_an_order_whose_collision_table_does_not_fit_is_refused_on_voxels(order, downwash, fits):
    """mrf.order takes 1..32, which the plane holds; on voxels the table grows with the cube of the stencil and with
    the downwash (order 32: 8.8 GB, ran out of memory in the first step). The scenario refuses it, naming the
    largest order that fits, and takes that one."""
    data = {"scenario": {"map": {"kind": "free", "size": [6, 6, 4]}, "start": {"positions": [[1, 1, 1], [3, 3, 1]]},
                         "goal": [5, 5, 1], "downwash": downwash}, "mrf": {"order": order}}
    with pytest.raises(ConfigError, match=rf"mrf.order = {order}: .* give at most {fits}$"):
        build_scenario(from_dict(data))
    build_scenario(from_dict({**data, "mrf": {"order": fits}}))
    planar = {"scenario": {"map": {"kind": "free", "size": [6, 6]}, "start": {"positions": [[1, 1], [3, 3]]},
                           "goal": [5, 5]}, "mrf": {"order": 32}}
    build_scenario(from_dict(planar))


# ------------------------------------------------------------------ goal field on voxels


def brute_graph(free, order):
    """The search graph built move by move with segment_clear (the motion rule), edges weighted by length."""
    G = nx.DiGraph()
    moves = graph_moves(order, 3)
    for c in map(tuple, np.argwhere(free).tolist()):
        G.add_node(c)
        for m in moves:
            q = tuple(np.array(c) + m)
            if segment_clear(free, np.array(c, float), np.array(q, float)):
                G.add_edge(c, q, weight=float(np.linalg.norm(m)))
    return G


@pytest.mark.parametrize("order, degree", [(1, 6), (2, 18), (3, 26), (5, 26)])
def test_goal_distance_on_voxels_matches_dijkstra(order, degree):
    rng = np.random.default_rng(order)
    free = rng.random((5, 4, 4)) > 0.25
    goal = np.argwhere(free)[0]
    assert len(graph_moves(order, 3)) == degree
    gd = goal_distance(free, goal, resolution=0.5, order=order)
    G = brute_graph(free, order)
    dist = nx.single_source_dijkstra_path_length(G.reverse(), tuple(goal.tolist()))
    for c in np.ndindex(free.shape):
        expect = dist.get(c, np.inf) * 0.5 if free[c] else np.inf
        assert gd.path[c] == pytest.approx(expect), c
        if np.isfinite(expect) and c != tuple(goal.tolist()):
            nxt = tuple(gd.next_cell[c].tolist())
            assert G.has_edge(c, nxt)  # one move of the label set


@pytest.mark.parametrize("seed", range(5))
def test_the_geodesic_static_field_on_voxels_has_no_local_minimum_but_the_goal(seed):
    rng = np.random.default_rng(seed)
    free = rng.random((10, 8, 6)) > 0.3
    goal = np.argwhere(free)[rng.integers(free.sum())]
    prob = (~free).astype(float)
    g_cfg, o_cfg = GoalPotentialConfig(), ObstaclePotentialConfig()
    for order in (2, 3):
        gd = goal_distances(prob, goal, 1.0, g_cfg, o_cfg, order)
        static = static_field(prob, goal, 1.0, g_cfg, o_cfg, order, gd)
        assert static.shape == free.shape
        ends = descent_ends(free, static, order)
        reach = np.isfinite(gd.path)
        # steepest descent over the label moves ends at the goal from every connected voxel
        assert np.all(ends[reach] == goal)
        # and the goal's next-cell moves lower rho_S by at least a_G / k_G per metre
        cells = np.argwhere(reach & ~np.all(np.indices(free.shape).T.swapaxes(0, 2) == goal, axis=-1))
        nxt = gd.next_cell[tuple(cells.T)]
        drop = static[tuple(cells.T)] - static[tuple(nxt.T)]
        assert np.all(drop >= g_cfg.a / g_cfg.k * np.linalg.norm(nxt - cells, axis=1) - 1e-9)


def test_straight_goal_field_in_3d():
    prob = np.zeros((5, 4, 3))
    s = static_field(prob, np.array([1, 2, 0]), 1.0, GoalPotentialConfig(distance="euclidean"),
                     ObstaclePotentialConfig())
    cfg = GoalPotentialConfig()
    assert s[4, 0, 2] == pytest.approx(cfg.a * np.exp(np.sqrt(9 + 4 + 4) / cfg.k))


def test_obstacle_potential_blurs_in_three_axes():
    prob = np.zeros((9, 9, 9))
    prob[4, 4, 4] = 1.0
    s = static_field(prob, None, 1.0, GoalPotentialConfig(), ObstaclePotentialConfig())
    assert s[4, 4, 5] == pytest.approx(s[4, 5, 4]) and s[4, 4, 5] == pytest.approx(s[5, 4, 4]) and s[4, 4, 5] > 0


# ------------------------------------------------------------------ interaction graph


@pytest.mark.parametrize("seed", range(4))
def test_knn_and_cliques_in_3d(seed):
    rng = np.random.default_rng(seed)
    pts = np.unique(rng.integers(0, 8, (40, 3)), axis=0)
    k = int(rng.integers(2, 8))
    edges = knn_edges(pts, k)
    d = np.linalg.norm(pts[:, None] - pts[None], axis=-1)
    expect = set()
    for i in range(len(pts)):
        order = sorted(range(len(pts)), key=lambda j: (round(d[i, j], 9), j))
        for j in [j for j in order if j != i][:k]:
            expect.add((min(i, j), max(i, j)))
    assert {tuple(e) for e in edges.tolist()} == expect
    G = nx.Graph()
    G.add_nodes_from(range(len(pts)))
    G.add_edges_from(edges.tolist())
    assert sorted(c.tolist() for c in maximal_cliques(len(pts), edges)) == sorted(sorted(c) for c in nx.find_cliques(G))


# ------------------------------------------------------------------ safety checks


def test_each_safety_check_fires_in_3d():
    free = np.ones((6, 6, 6), bool)
    free[3, 3, 3] = False
    ok = np.array([[[0, 0, 0], [0, 0, 2]], [[1, 0, 0], [1, 0, 2]]])  # two robots 2 voxels apart in z, moving together
    assert discrete_violations(ok, free, downwash=2.0) == []
    cases = {
        # stacked one voxel apart with c = 2: at the start, and after a step
        "at the start": (np.array([[[0, 0, 0], [0, 0, 1]]]), 2.0),
        "while moving": (np.array([[[0, 0, 0], [1, 0, 1]], [[1, 0, 0], [1, 0, 1]]]), 2.0),  # slides under
        "stacked after a move": (np.array([[[0, 0, 0], [1, 0, 2]], [[1, 0, 0], [1, 0, 1]]]), 2.0),
        "share cell": (np.array([[[0, 0, 0], [2, 0, 0]], [[1, 0, 0], [1, 0, 0]]]), 1.0),
        "occupied cell": (np.array([[[3, 3, 2]], [[3, 3, 3]]]), 1.0),
        "cuts an obstacle": (np.array([[[2, 2, 2]], [[3, 3, 2]], [[4, 4, 3]]]), 1.0),  # space diagonal past a voxel
        "off the map": (np.array([[[0, 0, 0]], [[0, 0, -1]]]), 1.0),
    }
    words = {"at the start": "at the start", "while moving": "while moving", "stacked after a move": "while moving",
             "share cell": "share cell", "occupied cell": "occupied cell", "cuts an obstacle": "cuts an obstacle",
             "off the map": "off the map"}
    for name, (paths, c) in cases.items():
        found = discrete_violations(paths, free, downwash=c)
        assert any(words[name] in v for v in found), (name, found)
        assert found == discrete_violations_brute_force(paths, free, downwash=c), name
    # the same stacked pair is fine without downwash: the metric is what fires
    assert discrete_violations(cases["at the start"][0], free, downwash=1.0) == []
    assert discrete_violations(cases["while moving"][0], free, downwash=1.0) == []


@pytest.mark.parametrize("seed", range(8))
def test_indexed_check_equals_all_pairs_in_3d(seed):
    rng = np.random.default_rng(seed)
    free = rng.random((12, 12, 8)) > 0.1
    cells = np.argwhere(free)
    n = int(rng.integers(2, 40))
    pos = cells[rng.choice(len(cells), n, replace=False)]
    off = stencil(int(rng.choice([1, 2, 3])), 3)
    paths = [pos]
    for _ in range(5):
        pos = pos + off[rng.integers(0, len(off), n)]
        paths.append(pos)
    paths = np.stack(paths)
    c = float(rng.choice([1.0, 2.0, 3.0]))
    for limit in (10, 10**6):
        assert discrete_violations(paths, free, limit, c) == discrete_violations_brute_force(paths, free, limit, c)


def test_step_min_separation_is_scaled():
    p = np.array([[0, 0, 0], [0, 0, 2], [5, 5, 5]])
    assert step_min_separation(p, p, 2.0)[0] == pytest.approx(1.0)
    assert step_min_separation(p, p, 4.0)[0] == pytest.approx(0.5)


# ------------------------------------------------------------------ planner


def window_map():
    """32 x 16 x 8 voxels, a wall at x = 15, 16 with a 6 x 4 window (y 5..10, z 2..5)."""
    free = np.ones((32, 16, 8), bool)
    free[15:17] = False
    free[15:17, 5:11, 2:6] = True
    return free


def window_problem(n, downwash=2.0, order=2, seed=0, method_k=7):
    free = window_map()
    prob = (~free).astype(float)
    goal = np.array([28, 8, 4])
    rng = np.random.default_rng(seed)
    lattice = np.array([(x, y, z) for x in range(1, 11) for y in range(1, 15) for z in (1, 3, 5)])
    start = lattice[rng.choice(len(lattice), n, replace=False)]
    gd = goal_distances(prob, goal, 1.0, GoalPotentialConfig(), ObstaclePotentialConfig(), order)
    static = static_field(prob, goal, 1.0, GoalPotentialConfig(), ObstaclePotentialConfig(), order, gd)
    return DiscreteProblem(free=free, static=static, start=start, goal=goal, morse=Morse(), k=method_k, order=order,
                           goal_distance=gd.field, goal_path=gd.path,
                           goal_region_radius=goal_region_radius(gd.path, n, 3.0), downwash=downwash, follow=True)


def dense_check(paths, free, c):
    """Every pair >= 1 cell apart (scaled) at SAMPLES points of every step, and every moving
    sample >= 0.5 from every occupied voxel (off the map is occupied): sampling, no library geometry."""
    occ = np.argwhere(np.pad(~free, 1, constant_values=True)).astype(float) - 1
    occ_tree = cKDTree(occ)
    s = np.linspace(0, 1, 101)[:, None, None]
    for t in range(1, len(paths)):
        a, b = paths[t - 1].astype(float), paths[t].astype(float)
        pos = a[None] + s * (b - a)[None]  # (S, N, 3)
        iu, ju = np.triu_indices(pos.shape[1], 1)
        d = scaled_norm(pos[:, iu] - pos[:, ju], c)
        assert d.min() >= 1 - 1e-9, (t, d.min())
        moving = np.any(a != b, axis=1)
        if moving.any():
            pts = pos[:, moving].reshape(-1, 3)
            # a cube closer than 0.5 to a point has its centre within 0.5 + sqrt(3) / 2 of it
            for k, near in enumerate(occ_tree.query_ball_point(pts, 0.5 + np.sqrt(3) / 2 + 1e-6)):
                if near:
                    g = np.maximum(np.abs(pts[k] - occ[near]) - 0.5, 0)
                    assert np.linalg.norm(g, axis=-1).min() >= 0.5 - 1e-9, t


def test_a_swarm_through_a_window_with_downwash():
    p = window_problem(40, downwash=2.0)
    plan = plan_discrete(p, max_steps=300, arrival=True)
    assert plan.stop_reason == "arrived" and plan.converged
    end = plan.paths[-1]
    assert np.all(p.goal_path[tuple(end.T)] <= p.goal_region_radius)  # every robot at the goal
    assert plan.paths.shape[1:] == (40, 3)
    assert discrete_violations(plan.paths, p.free, downwash=2.0) == []
    dense_check(plan.paths, p.free, 2.0)
    # never a robot in the voxel right above another
    for x in plan.paths:
        cols = {}
        for c in map(tuple, x.tolist()):
            for z in cols.get(c[:2], []):
                assert abs(z - c[2]) >= 2
            cols.setdefault(c[:2], []).append(c[2])


def test_a_start_closer_than_the_downwash_allows_is_refused():
    p = window_problem(10)
    start = p.start.copy()
    start[1] = start[0] + [0, 0, 1]
    bad = DiscreteProblem(**{**p.__dict__, "start": start})
    with pytest.raises(ScenarioError, match="downwash-scaled"):
        plan_discrete(bad, max_steps=2)
    # the same start is fine without downwash
    plan_discrete(DiscreteProblem(**{**p.__dict__, "start": start, "downwash": 1.0}), max_steps=2)


def test_a_start_of_the_wrong_dimension_is_refused():
    p = window_problem(10)
    with pytest.raises(ScenarioError, match="axes"):
        plan_discrete(DiscreteProblem(**{**p.__dict__, "start": p.start[:, :2]}), max_steps=2)


def test_pruning_in_3d_equals_brute_force():
    p = window_problem(12, order=3)
    plan = plan_discrete(p, max_steps=25)
    for h in (3, 4):
        fast = prune_paths(plan.paths, p.free, h)
        slow = prune_paths_brute_force(plan.paths, p.free, h)
        assert [a.tolist() for a in fast] == [b.tolist() for b in slow]
        assert any(len(a) < plan.n_steps + 1 for a in fast)  # it prunes something
