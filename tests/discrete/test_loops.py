"""Dropping a robot's loops: back in a cell it left, it waits there instead (``mrf.drop_loops``)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from mrfswarm.config import apply_overrides, from_dict
from mrfswarm.discrete.loops import drop_loops, returns
from mrfswarm.discrete.merge_waits import CellIndex, robot_clear, waits_clear
from mrfswarm.discrete.safety import discrete_violations
from mrfswarm.geometry import downwash_scale
from mrfswarm.pipeline import plan

EXPERIMENTS = Path(__file__).resolve().parents[2] / "experiments"


def cells(paths: np.ndarray, robot: int) -> list[tuple[int, ...]]:
    """The robot's cells in order, waits dropped."""
    out: list[tuple[int, ...]] = []
    for c in paths[:, robot]:
        if not out or out[-1] != tuple(c):
            out.append(tuple(int(v) for v in c))
    return out


def subsequence(short: list, long: list) -> bool:
    it = iter(long)
    return all(c in it for c in short)


def test_returns_are_the_later_steps_back_in_a_cell_after_leaving_it():
    # A A B A C A: from step 0 (and 1, the same visit) the robot comes back at 3 and 5; a wait is no loop
    col = np.array([[0, 0], [0, 0], [1, 0], [0, 0], [0, 1], [0, 0]])
    assert returns(col) == [[5, 3], [5, 3], [], [5], [], []]


def test_returns_on_random_walks_match_their_definition():
    """Against the definition, scanned step by step: u > s is a return of s when the robot is in s's cell at u
    and left it at some step between."""
    rng = np.random.default_rng(3)
    for _ in range(50):
        col = np.cumsum(rng.integers(-1, 2, size=(int(rng.integers(1, 40)), 2)) * (rng.random((1, 1)) < 0.7), axis=0)
        col = np.clip(col, -2, 2)  # a small box: many returns, long stays
        T = len(col) - 1
        want = []
        for s in range(T + 1):
            left = [t for t in range(s + 1, T + 1) if (col[t] != col[s]).any()]
            want.append([u for u in range(T, s, -1) if left and u > left[0] and (col[u] == col[s]).all()])
        assert returns(col) == want


def test_a_lone_robots_round_trip_becomes_a_wait():
    # A -> B -> C -> B -> A -> D: the whole round from A is dropped
    col = np.array([[0, 0], [1, 0], [2, 0], [1, 0], [0, 0], [0, 1]])
    out, dropped = drop_loops(col[:, None])
    assert dropped == 1
    np.testing.assert_array_equal(out[:, 0], [[0, 0]] * 5 + [[0, 1]])


def stepping_aside() -> np.ndarray:
    """Robot 0 steps aside from (2, 2) to (2, 3) and back while robot 1 passes through (2, 2) along y = 2."""
    r0 = [(2, 2), (2, 3), (2, 3), (2, 3), (2, 3), (2, 2)]
    r1 = [(0, 2), (1, 2), (2, 2), (3, 2), (4, 2), (5, 2)]
    return np.array([r0, r1]).transpose(1, 0, 2)


def test_a_loop_that_makes_way_for_a_neighbour_is_kept():
    paths, free = stepping_aside(), np.ones((7, 6), dtype=bool)
    assert discrete_violations(paths, free) == []
    out, dropped = drop_loops(paths)
    assert dropped == 0
    np.testing.assert_array_equal(out, paths)


@pytest.mark.parametrize("off", ["robot_clear", "waits_clear"])
def test_the_guard_alone_keeps_the_drop_safe(off, monkeypatch):
    """With the separation checks switched off (the steps' tests of the waits, then robot_clear of a loop they
    pass), the kept loop above is dropped and the robots collide; with either one on, it is kept."""
    import mrfswarm.discrete.loops as lp

    monkeypatch.setattr(lp, off, lambda *a: np.ones(len(a[3]), dtype=bool) if off == "waits_clear" else True)
    assert lp.drop_loops(stepping_aside())[1] == 0
    monkeypatch.setattr(lp, "robot_clear", lambda *a: True)
    monkeypatch.setattr(lp, "waits_clear", lambda *a: np.ones(len(a[3]), dtype=bool))
    unguarded, dropped = lp.drop_loops(stepping_aside())
    assert dropped == 1
    assert discrete_violations(unguarded, np.ones((7, 6), dtype=bool)) != []


def test_where_the_long_loop_is_blocked_the_loop_inside_it_is_dropped():
    # robot 0: A = (2, 2) -> (2, 3) -> (2, 4) -> (2, 3) -> (2, 3) -> A; robot 1 passes through A while robot 0
    # is away, so the loop from A stays, but the round (2, 3) -> (2, 4) -> (2, 3) inside it goes
    r0 = [(2, 2), (2, 3), (2, 4), (2, 3), (2, 3), (2, 2)]
    r1 = [(0, 2), (0, 2), (1, 2), (2, 2), (3, 2), (4, 2)]
    paths = np.array([r0, r1]).transpose(1, 0, 2)
    assert discrete_violations(paths, np.ones((6, 6), dtype=bool)) == []
    out, dropped = drop_loops(paths)
    assert dropped == 1
    np.testing.assert_array_equal(out[:, 0], [(2, 2), (2, 3), (2, 3), (2, 3), (2, 3), (2, 2)])
    np.testing.assert_array_equal(out[:, 1], paths[:, 1])


def test_downwash_counts_in_the_check():
    # robot 0 leaves A = (2, 0, 0) for (3, 0, 0) and comes back; meanwhile robot 1 flies over A, 2 voxels up.
    # Waiting at A instead: 2 voxels below robot 1, apart in the plain metric, 2 / 3 of a voxel with c = 3
    r0 = np.array([[2, 0, 0], [3, 0, 0], [3, 0, 0], [3, 0, 0], [2, 0, 0]])
    r1 = np.array([[0, 0, 2], [1, 0, 2], [2, 0, 2], [1, 0, 3], [0, 0, 3]])
    paths = np.stack([r0, r1], axis=1)
    assert discrete_violations(paths, np.ones((5, 1, 4), dtype=bool), downwash=3.0) == []
    assert drop_loops(paths, downwash=1.0)[1] == 1
    out, dropped = drop_loops(paths, downwash=3.0)
    assert dropped == 0
    np.testing.assert_array_equal(out, paths)


def clutter(seed: int) -> dict:
    sys.path.insert(0, str(EXPERIMENTS / "bench"))
    import flight_quality as fq

    occ = fq._random_field(64, 64, 0.10, seed, (8, 8), (55, 55), 5)
    scn = {"map": {"kind": "ascii", "rows": fq._rows(occ)},
           "start": {"center": [8, 8], "n_robots": 40, "sigma": 2.5, "seed": 0}, "goal": [55, 55]}
    return {"scenario": scn, "interaction": {"k": 7}}


def test_a_clutter_plan_loses_its_loops_and_keeps_its_cells_and_the_invariant():
    """A 64 x 64 clutter map of 40 robots (seed 3 of the random clutter maps): 17 loops in the MRF's paths."""
    data = apply_overrides(clutter(3), ["smoothing.enabled=false", "simulation.enabled=false", "mrf.contested=downhill",
                                       "mrf.straighten=false"])
    raw = plan(from_dict(apply_overrides(data, ["mrf.drop_loops=false", "mrf.merge_waits=false"]), EXPERIMENTS),
               progress=False)
    kept = plan(from_dict(apply_overrides(data, ["mrf.merge_waits=false"]), EXPERIMENTS), progress=False)
    P, Q = raw.discrete.paths, kept.discrete.paths
    assert raw.discrete.dropped_loops == 0 and kept.discrete.dropped_loops >= 10
    assert P.shape == Q.shape
    np.testing.assert_array_equal(P[[0, -1]], Q[[0, -1]])
    for i in range(P.shape[1]):
        assert subsequence(cells(Q, i), cells(P, i))
    assert discrete_violations(Q, kept.scenario.grid.free) == []
    moves = lambda X: int(np.any(np.diff(X, axis=0) != 0, axis=2).sum())  # noqa: E731
    assert moves(Q) < moves(P)
    assert kept.summary()["dropped_loops"] == kept.discrete.dropped_loops


def test_the_paper_configs_keep_the_mrfs_paths():
    cfg = from_dict(apply_overrides(__import__("tomllib").loads((EXPERIMENTS / "corridor.toml").read_text()),
                                    ["smoothing.enabled=false", "simulation.enabled=false"]), EXPERIMENTS)
    assert cfg.mrf.drop_loops is False
    assert plan(cfg, progress=False).discrete.dropped_loops == 0


def crowd(rng: np.random.Generator, n: int, steps: int, dim: int, box: int, reach: int = 1) -> np.ndarray:
    """(steps + 1, n, dim) random walks of up to ``reach`` cells per axis and step (``mrf.order`` > 2 moves two),
    held in a box of side ``box``: crowded robots that come back to cells they left."""
    start = rng.integers(0, box, size=(1, n, dim))
    moves = rng.integers(-reach, reach + 1, size=(steps, n, dim)) * (rng.random((steps, n, 1)) < 0.6)
    return np.clip(np.concatenate([start, moves]).cumsum(axis=0), 0, box - 1)


@pytest.mark.parametrize("dim, downwash, reach", [(2, 1.0, 1), (2, 1.0, 2), (3, 2.0, 1), (3, 2.0, 2)])
def test_each_step_of_a_wait_is_tested_as_robot_clear_tests_it(dim, downwash, reach):
    """waits_clear, a robot's wait at one cell tested step by step against the robots a CellIndex finds near, against
    robot_clear of each step and of the whole wait against every robot: the same answers, on crowds where both
    occur."""
    rng = np.random.default_rng(10 * dim + reach)
    scale = downwash_scale(dim, downwash)
    answers = []
    for _ in range(100):
        paths = crowd(rng, 30, 12, dim, 4 + 3 * reach, reach)
        largest = float(np.abs(np.diff(paths, axis=0)).max())
        robot = int(rng.integers(30))
        s, u = sorted(int(v) for v in rng.choice(13, size=2, replace=False))
        own = paths[:, robot].copy()
        own[s:u + 1] = paths[s, robot]
        steps = np.arange(s, u)
        got = waits_clear(paths, robot, own[steps], steps, scale, largest, CellIndex(paths))
        assert got.tolist() == [robot_clear(paths, robot, t, t + 1, scale, own, largest) for t in steps.tolist()]
        assert got.all() == robot_clear(paths, robot, s, u, scale, own, largest)
        answers.append(bool(got.all()))
    assert 0.1 < np.mean(answers) < 0.9


def drop_loops_checking_each(paths: np.ndarray, downwash: float) -> tuple[np.ndarray, int]:
    """The reference: drop_loops checking each loop alone with robot_clear against every robot (no index)."""
    P = np.array(paths, dtype=np.int64)
    T, N = len(P) - 1, P.shape[1]
    scale = downwash_scale(P.shape[-1], downwash)
    largest = float(np.abs(np.diff(P, axis=0)).max())
    dropped = 0
    while True:
        before = dropped
        for i in range(N):
            later, s = returns(P[:, i]), 0
            while s < T - 1:
                for u in later[s]:
                    col = P[:, i].copy()
                    col[s + 1:u] = P[s, i]
                    if robot_clear(P, i, s, u, scale, col, largest):
                        P[:, i], dropped, s = col, dropped + 1, u - 1
                        break
                s += 1
        if dropped == before:
            return P, dropped


@pytest.mark.parametrize("dim, downwash", [(2, 1.0), (3, 2.0)])
@pytest.mark.parametrize("reach", [1, 2])
@pytest.mark.parametrize("seed", range(3))
def test_dropping_with_the_index_drops_what_checking_each_loop_drops(dim, downwash, reach, seed, monkeypatch):
    """drop_loops tests the steps of a robot's loops at once against the robots near (a CellIndex kept as loops are
    dropped), and checks those that pass with robot_clear and that index; the index must be the plan's at every
    check, and the paths and count those of checking each loop against every robot, on crowds (downwash-scaled in
    3-D) where loops are both dropped and kept."""
    import mrfswarm.discrete.loops as lp

    rng = np.random.default_rng(seed)
    paths = crowd(rng, 40, 30, dim, 9, reach)
    checks = []

    def checked(P, robot, first, last, scale, own, largest_move, index):
        np.testing.assert_array_equal(index.keys % 40, CellIndex(P).keys % 40)  # each step's robots in order
        checks.append(robot_clear(P, robot, first, last, scale, own, largest_move, index))
        return checks[-1]

    monkeypatch.setattr(lp, "robot_clear", checked)
    fast, n_fast = lp.drop_loops(paths, downwash)
    slow, n_slow = drop_loops_checking_each(paths, downwash)
    assert n_fast == n_slow
    np.testing.assert_array_equal(fast, slow)
    kept = sum(any(returns(slow[:, i])) for i in range(slow.shape[1]))  # robots left with a loop
    assert n_slow >= 5 and kept >= 5 and sum(checks) == n_slow
