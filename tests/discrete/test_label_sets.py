"""Label sets, motion clearance, and the step's hard conflicts against brute force."""

import numpy as np
import pytest

from mrfswarm.discrete.label_sets import LabelSets, label_sets
from mrfswarm.discrete.motion import min_distance_during_move, moves_clear, stencil, step_min_separation, swept_cells
from mrfswarm.discrete.step_mrf import conflict_tables
from mrfswarm.geometry import segment_box_distance, segment_clear


@pytest.mark.parametrize("n, size", [(1, 5), (2, 9), (4, 13), (5, 21), (8, 25)])
def test_stencil(n, size):
    s = stencil(n)
    assert len(s) == size and s[0].tolist() == [0, 0]
    assert np.all((s**2).sum(1) <= n) and len(np.unique(s, axis=0)) == size


def brute_min_distance(d0, v, samples=20001):
    s = np.linspace(0, 1, samples)[:, None]
    return np.hypot(*(d0 + s * v).T).min()


def test_min_distance_during_move_matches_sampling():
    rng = np.random.default_rng(0)
    for _ in range(200):
        d0, v = rng.integers(-4, 5, 2).astype(float), rng.integers(-4, 5, 2).astype(float)
        assert min_distance_during_move(d0, v) == pytest.approx(brute_min_distance(d0, v), abs=1e-3)


def test_swept_cells_by_brute_force():
    # a cell is required iff its square comes closer than half a cell to the move's segment
    for n in (1, 2, 4, 8):
        cells, count = swept_cells(n)
        for s, o in enumerate(stencil(n)):
            req = {tuple(c) for c in cells[s, : count[s]].tolist()}
            for x in range(-4, 5):
                for y in range(-4, 5):
                    pts = np.linspace(0, 1, 4001)[:, None] * o
                    g = np.maximum(0, np.abs(pts - [x, y]) - 0.5)
                    d = np.hypot(*g.T).min()
                    if abs(d - 0.5) > 1e-3:  # avoid sampling noise right at the boundary
                        assert ((x, y) in req) == (d < 0.5), (n, o, x, y, d)


def test_moves_clear_agrees_with_segment_clear():
    rng = np.random.default_rng(1)
    free = rng.random((15, 15)) > 0.3
    starts = np.argwhere(free)
    for n in (2, 5, 8):
        S = len(stencil(n))
        ok = moves_clear(free, starts, np.broadcast_to(np.arange(S), (len(starts), S)), n)
        for i in range(0, len(starts), 7):
            for s, o in enumerate(stencil(n)):
                assert ok[i, s] == segment_clear(free, starts[i], starts[i] + o), (starts[i], o)


def test_segment_box_distance_cases():
    assert segment_box_distance(np.array([0, 0.0]), np.array([1, 1.0]), np.array([1.0, 0])) == pytest.approx(0.0)
    assert segment_box_distance(np.array([0, 0.0]), np.array([2, 0.0]), np.array([1.0, 1])) == pytest.approx(0.5)
    assert segment_box_distance(np.array([0, 0.0]), np.array([0, 0.0]), np.array([2.0, 2])) == pytest.approx(np.hypot(1.5, 1.5))


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("order", [1, 2, 4, 8])
def test_label_set_heuristics(seed, order):
    rng = np.random.default_rng(seed)
    W = H = 18
    free = rng.random((W, H)) > 0.25
    cells = np.argwhere(free)
    rng.shuffle(cells)
    starts = cells[:25]
    goal = np.array([17, 9])
    for trim in (False, True):
        ls = label_sets(free, starts, order, goal, trim_backward=trim)
        assert np.all(ls.index[:, 0] == 0) and np.all(ls.count >= 1)  # stay first, always there
        owner = {}
        others = {tuple(c) for c in starts.tolist()}
        for i in range(len(starts)):
            for l in range(ls.count[i]):
                c = tuple(ls.cells[i, l].tolist())
                assert c not in owner, "X_i and X_j must be disjoint"
                owner[c] = i
                assert free[c], "labels are free cells"
                if l > 0:
                    assert c not in others, "no label on another robot's (or one's own) current cell"
                    o = ls.offsets[i, l]
                    assert (o**2).sum() <= order
                    assert segment_clear(free, starts[i], starts[i] + o)
                    if trim:
                        assert o @ (goal - starts[i]) >= 0


def brute_conflicts(ls, i, j):
    """(L, L) bool by sampling the relative motion of robots i and j for every label pair."""
    s = np.linspace(0, 1, 1001)[:, None, None, None]
    d0 = (ls.starts[i] - ls.starts[j]).astype(float)
    v = (ls.offsets[i][:, None, :] - ls.offsets[j][None, :, :]).astype(float)
    dist = np.hypot(*np.moveaxis(d0 + s * v, -1, 0)).min(axis=0)
    return (dist < 1 - 1e-6) & ls.valid[i][:, None] & ls.valid[j][None, :]


def check_conflicts(ls):
    pairs, mask = conflict_tables(ls)
    table = {tuple(p): m for p, m in zip(pairs.tolist(), mask)}
    n_true = 0
    reach = 2 * np.sqrt(ls.order) + 1  # farther apart, two moves cannot come within 1
    for i in range(len(ls.starts)):
        for j in range(i + 1, len(ls.starts)):
            if np.hypot(*(ls.starts[i] - ls.starts[j])) > reach:
                assert (i, j) not in table
                continue
            expect = brute_conflicts(ls, i, j)
            got = table.get((i, j), np.zeros_like(expect))
            np.testing.assert_array_equal(got, expect, err_msg=f"robots {i}, {j}")
            n_true += int(expect.sum())
    return n_true


@pytest.mark.parametrize("order", [1, 2, 4, 8])
def test_conflicts_match_brute_force(order):
    rng = np.random.default_rng(order)
    free = np.ones((14, 14), bool)
    cells = np.argwhere(free)
    rng.shuffle(cells)
    starts = cells[:20]
    check_conflicts(label_sets(free, starts, order))
    # Full, overlapping stencils (what a label rule without the paper's heuristics, or a
    # neighbour blocked by a wall, gives): many real conflicts, each must be found.
    dense = cells[(np.abs(cells - 7) <= 2).all(axis=1)][:8]
    S = len(stencil(order))
    full = LabelSets(index=np.tile(np.arange(S), (len(dense), 1)), count=np.full(len(dense), S), starts=dense,
                     order=order)
    assert check_conflicts(full) > 0


def test_diagonal_swap_is_a_conflict():
    ls = LabelSets(index=np.tile(np.arange(9), (2, 1)), count=np.array([9, 9]), starts=np.array([[0, 0], [1, 0]]),
                   order=2)
    pairs, mask = conflict_tables(ls)
    a = next(k for k, o in enumerate(stencil(2).tolist()) if o == [1, 1])
    b = next(k for k, o in enumerate(stencil(2).tolist()) if o == [-1, 1])
    assert pairs.tolist() == [[0, 1]] and mask[0, a, b]
    assert not mask[0, 0, 0]  # both staying is always allowed


def test_step_min_separation_checks_all_pairs():
    p0 = np.array([[0, 0], [1, 0], [10, 10]])
    p1 = np.array([[1, 1], [0, 1], [10, 11]])  # robots 0 and 1 swap across a diagonal: they meet
    d, pair = step_min_separation(p0, p1)
    assert d == pytest.approx(0.0) and pair == (0, 1)
    d, _ = step_min_separation(p0, p0)
    assert d == pytest.approx(1.0)


@pytest.mark.parametrize("contested", ["nearest", "downhill"])
@pytest.mark.parametrize("seed", range(4))
def test_a_contested_cell_goes_to_a_nearest_claimant_ties_by_rule(seed, contested):
    """Brute force over every claimant of every cell: the owner is one of the nearest; among
    equally near ones, the lower index ("nearest") or the one the cell lowers most ("downhill")."""
    rng = np.random.default_rng(seed)
    free = rng.random((16, 16)) > 0.2
    cells = np.argwhere(free)
    rng.shuffle(cells)
    starts = cells[:30]  # packed: many contested cells
    static = rng.normal(size=free.shape).round(1)  # coarse values: ties in the rise too
    order = 2
    ls = label_sets(free, starts, order, static=static, contested=contested)
    occupied = {tuple(c) for c in starts.tolist()}
    claim: dict[tuple, list[int]] = {}
    for i, s in enumerate(starts):
        for o in stencil(order)[1:]:
            c = tuple((s + o).tolist())
            if 0 <= c[0] < 16 and 0 <= c[1] < 16 and c not in occupied and segment_clear(free, s, s + o):
                claim.setdefault(c, []).append(i)
    owner = {tuple(ls.cells[i, l].tolist()): i for i in range(len(starts)) for l in range(1, ls.count[i])}
    contested_cells = 0
    for c, who in claim.items():
        d2 = [int(((np.array(c) - starts[i]) ** 2).sum()) for i in who]
        near = [i for i, d in zip(who, d2) if d == min(d2)]
        if contested == "nearest":
            expect = min(near)
        else:
            rise = {i: static[c] - static[tuple(starts[i])] for i in near}
            expect = min(near, key=lambda i: (rise[i], i))
        assert owner.get(c) == expect, (c, who, near)
        contested_cells += len(who) > 1
    assert contested_cells > 10


def test_contested_rule_is_checked():
    free = np.ones((4, 4), bool)
    with pytest.raises(ValueError, match="label sets need one of shared, downhill, nearest"):
        label_sets(free, np.array([[0, 0]]), 2, contested="random")
    with pytest.raises(ValueError, match="label sets need one of"):  # "auto" is the planner's, per plan
        label_sets(free, np.array([[0, 0]]), 2, contested="auto")
    with pytest.raises(ValueError, match="needs the static field"):
        label_sets(free, np.array([[0, 0]]), 2, contested="downhill")


def test_downwash_scale_shrinks_only_z():
    from mrfswarm.geometry import downwash_scale

    assert downwash_scale(2, 3.0).tolist() == [1.0, 1.0]
    assert downwash_scale(3, 2.0).tolist() == [1.0, 1.0, 0.5]
    # one voxel straight above is 0.5 cells away in the scaled metric with c = 2: not apart
    assert np.linalg.norm(np.array([0, 0, 1]) * downwash_scale(3, 2.0)) == 0.5
    for bad in [(3, 0.5), (3, float("nan")), (4, 1.0)]:
        with pytest.raises(ValueError, match="downwash_scale"):
            downwash_scale(*bad)


@pytest.mark.parametrize("seed", range(3))
def test_a_shared_contested_cell_stays_with_every_claimant_and_its_conflicts_are_found(seed):
    """contested = "shared": every robot that can move to a cell keeps it (no X_i ∩ X_j = ∅), and the step's
    hard conflicts, which then decide who takes it, match brute force on those overlapping sets."""
    rng = np.random.default_rng(seed)
    free = rng.random((16, 16)) > 0.2
    cells = np.argwhere(free)
    rng.shuffle(cells)
    starts = cells[:30]
    static = rng.normal(size=free.shape)
    ls = label_sets(free, starts, 2, static=static, contested="shared")
    occupied = {tuple(c) for c in starts.tolist()}
    for i, s in enumerate(starts):
        mine = {tuple(ls.cells[i, l].tolist()) for l in range(1, ls.count[i])}
        expect = {tuple((s + o).tolist()) for o in stencil(2)[1:]
                  if free[tuple(np.clip(s + o, 0, 15))] and 0 <= (s + o).min() and (s + o).max() < 16
                  and tuple((s + o).tolist()) not in occupied and segment_clear(free, s, s + o)}
        assert mine == expect, i
    owners = [sum(c in {tuple(ls.cells[i, l].tolist()) for l in range(1, ls.count[i])} for i in range(30))
              for c in {tuple(ls.cells[i, l].tolist()) for i in range(30) for l in range(1, ls.count[i])}]
    assert max(owners) > 1  # cells shared by several robots
    assert check_conflicts(ls) > 0


def test_shared_cells_are_kept_apart_by_the_steps_hard_conflicts(monkeypatch):
    """A plan with shared contested cells keeps every robot a cell from every other; without the hard conflicts
    (the guard that then decides who takes a cell) two robots end a step in one cell or cross within a cell, and
    the planner's invariant check refuses the plan."""
    import importlib

    from mrfswarm.config import from_dict
    from mrfswarm.discrete.safety import discrete_violations
    from mrfswarm.pipeline import plan

    rows = ["." * 24] * 16
    scn = {"map": {"kind": "ascii", "rows": rows}, "start": {"center": [5, 8], "n_robots": 20, "sigma": 1.5,
                                                             "seed": 1}, "goal": [20, 12]}
    cfg = from_dict({"scenario": scn, "interaction": {"k": 5}, "mrf": {"max_steps": 12, "merge_waits": False,
                                                                       "drop_loops": False, "contested": "shared"},
                     "smoothing": {"enabled": False}, "simulation": {"enabled": False}})
    assert cfg.mrf.contested == "shared"
    r = plan(cfg, progress=False)
    assert discrete_violations(r.discrete.paths, r.scenario.grid.free) == []
    none = lambda labels, downwash=1.0: (np.zeros((0, 2), np.intp),  # noqa: E731
                                         np.zeros((0, labels.index.shape[1], labels.index.shape[1]), bool))
    monkeypatch.setattr(importlib.import_module("mrfswarm.discrete.step_mrf"), "conflict_tables", none)
    with pytest.raises(AssertionError, match="discrete safety invariant violated.*(share cell|close while moving)"):
        plan(cfg, progress=False)  # the planner's own check refuses the plan
