"""Merging each robot's waits between runs of moves (``mrf.merge_waits``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mrfswarm.config import from_dict
from mrfswarm.discrete.merge_waits import merge_waits, robot_clear
from mrfswarm.discrete.safety import discrete_violations
from mrfswarm.pipeline import plan


def runs(paths: np.ndarray) -> int:
    """Runs of moves over all robots (a run starts where a robot moves after a wait or at the start)."""
    moving = np.any(np.diff(paths, axis=0) != 0, axis=2)
    return int(moving[0].sum() + (moving[1:] & ~moving[:-1]).sum())


def visits(paths: np.ndarray, robot: int) -> list[tuple[int, ...]]:
    """The robot's cells in order, waits dropped."""
    out: list[tuple[int, ...]] = []
    for c in paths[:, robot]:
        if not out or out[-1] != tuple(c):
            out.append(tuple(int(v) for v in c))
    return out


def line(pattern: str, y: int = 0, x0: int = 0) -> np.ndarray:
    """(len + 1, 2) one robot's path along x: "M" moves one cell, "." waits."""
    x = [x0]
    for ch in pattern:
        x.append(x[-1] + (ch == "M"))
    return np.array([[v, y] for v in x])


def test_a_lone_robots_stutter_becomes_one_run():
    paths = line("M.M.M.MM")[:, None]
    out, merged = merge_waits(paths)
    assert merged == 3
    assert "".join("M" if m else "." for m in np.any(np.diff(out[:, 0], axis=0) != 0, axis=1)) == "...MMMMM"
    assert visits(out, 0) == visits(paths, 0) and runs(out) == 1


def crossing() -> np.ndarray:
    """Robot 0 stutters (move, wait, move, wait) along y = 3; robot 1 steps into the cell robot 0 left, robot 2
    into the cell robot 0 moves to next, each just in time."""
    r0 = [(0, 3), (1, 3), (1, 3), (2, 3), (2, 3)]
    r1 = [(0, 4), (0, 4), (0, 3), (0, 3), (0, 3)]
    r2 = [(2, 5), (2, 4), (2, 3), (3, 3), (3, 3)]
    return np.array([r0, r1, r2]).transpose(1, 0, 2)


def test_a_merge_that_would_bring_robots_within_a_cell_is_refused():
    paths, free = crossing(), np.ones((6, 8), dtype=bool)
    assert discrete_violations(paths, free) == []
    # delaying robot 0's first move: it leaves (0, 3) while robot 1 enters it (0.71 cells apart); advancing its
    # second move: it enters (2, 3) with robot 2
    late, soon = paths.copy(), paths.copy()
    late[1, 0], soon[2, 0] = (0, 3), (2, 3)
    assert not robot_clear(late, 0, 0, 3, np.ones(2)) and not robot_clear(soon, 0, 0, 3, np.ones(2))
    out, merged = merge_waits(paths)
    assert merged == 0
    np.testing.assert_array_equal(out, paths)


def test_the_guard_alone_keeps_the_merge_safe(monkeypatch):
    """With the separation check switched off, the refused merge above breaks the invariant."""
    import mrfswarm.discrete.merge_waits as mw

    monkeypatch.setattr(mw, "robot_clear", lambda *a: True)
    monkeypatch.setattr(mw, "_first_blocks_clear", lambda paths, robot, tries, *a: np.ones(len(tries), dtype=bool))
    unguarded, merged = mw.merge_waits(crossing())
    assert merged == 1
    assert discrete_violations(unguarded, np.ones((6, 8), dtype=bool)) != []


def test_downwash_counts_in_the_check():
    # robot 1 hovers 2 voxels above robot 0's second cell: fine with c = 1, too close with c = 2 ...
    r0 = np.array([[0, 0, 0], [1, 0, 0], [1, 0, 0], [2, 0, 0]])
    r1 = np.array([[1, 0, 2], [1, 0, 2], [1, 0, 2], [1, 0, 2]])
    paths = np.stack([r0, r1], axis=1)
    assert robot_clear(paths, 0, 0, 3, np.ones(3))
    assert not robot_clear(paths, 0, 0, 3, np.array([1.0, 1.0, 1.0 / 3.0]))


@pytest.mark.parametrize("case", ["clutter", "doorway"])
def test_planned_paths_keep_their_cells_and_the_invariant(case):
    occ = np.zeros((30, 20), dtype=bool)
    if case == "doorway":
        occ[15, :] = True
        occ[15, 9:12] = False
    else:
        rng = np.random.default_rng(3)
        occ = rng.random((30, 20)) < 0.12
        occ[:9, 5:16] = False
        occ[22:, 5:16] = False
    rows = ["".join("@" if occ[x, y] else "." for x in range(occ.shape[0])) for y in range(occ.shape[1])]
    data = {"scenario": {"map": {"kind": "ascii", "rows": rows},
                         "start": {"center": [4, 10], "n_robots": 12, "sigma": 1.5, "seed": 1}, "goal": [26, 10]},
            # a cruise speed: no flight model, every safe merge is made (the model's choice is tested below)
            "interaction": {"k": 5}, "smoothing": {"enabled": False, "speed": 1.0}, "simulation": {"enabled": False},
            # the paper's Gamma, untrimmed: with the defaults (2, trimmed) the clutter plan has no wait to merge
            "obstacle_potential": {"gamma": 5.0}}
    plans = {m: plan(from_dict({**data, "mrf": {"merge_waits": m, "trim_backward": False}}, Path(".")), progress=False)
             for m in (False, True)}
    raw, merged = plans[False].discrete, plans[True].discrete
    assert merged.merged_waits > 0 and raw.merged_waits == 0
    assert discrete_violations(merged.paths, ~occ) == []
    assert merged.paths.shape == raw.paths.shape
    np.testing.assert_array_equal(merged.paths[[0, -1]], raw.paths[[0, -1]])
    for i in range(raw.paths.shape[1]):
        assert visits(merged.paths, i) == visits(raw.paths, i)
    assert runs(merged.paths) < runs(raw.paths)
    # the same merge applied by hand gives the same paths (the planner calls it once, at the end)
    np.testing.assert_array_equal(merge_waits(raw.paths)[0], merged.paths)


def test_a_merge_that_lengthens_the_modelled_flight_is_not_kept():
    """The doorway of the flight-quality bench with the paper's Gamma and no trim (with the defaults the plan has
    no wait):
    merging every wait moves two robots' stops apart (15.2 s by the time grid's model against 14.8 s unmerged);
    the model keeps only merges that do not cost time."""
    from mrfswarm.config import SmoothingConfig
    from mrfswarm.continuous.receding_horizon import flight_model

    occ = np.zeros((30, 20), dtype=bool)
    occ[15, :] = True
    occ[15, 9:12] = False
    rows = ["".join("@" if occ[x, y] else "." for x in range(30)) for y in range(20)]
    data = {"scenario": {"map": {"kind": "ascii", "rows": rows},
                         "start": {"center": [6, 10], "n_robots": 5, "sigma": 1.0, "seed": 0}, "goal": [25, 10]},
            "interaction": {"k": 3}, "mrf": {"merge_waits": False, "trim_backward": False}, "smoothing": {"enabled": False},
            "simulation": {"enabled": False}, "obstacle_potential": {"gamma": 5.0}}
    raw = plan(from_dict(data, Path(".")), progress=False).discrete.paths
    model = flight_model(SmoothingConfig(), 1.0, 0.25)
    assert model is not None

    def flight_time(p: np.ndarray) -> float:
        needs, lengths = model.needs(p)
        return model.duration(needs.max(axis=1), lengths.max(axis=1))

    every, n_every = merge_waits(raw)
    kept, n_kept = merge_waits(raw, flight=model)
    assert n_every > n_kept
    assert flight_time(every) > flight_time(raw) + 0.1  # the merges the model exists to refuse
    assert flight_time(kept) <= flight_time(raw) + 1e-9
    assert discrete_violations(kept, ~occ) == []


def _clear_all_pairs(paths: np.ndarray, robot: int, first: int, last: int, scale: np.ndarray,
                     own: np.ndarray) -> bool:
    """The reference: every other robot, every step, the exact closest approach (no locality filter)."""
    from mrfswarm.discrete.motion import min_distance_during_move

    for s in range(first, last):
        for j in range(paths.shape[1]):
            if j == robot:
                continue
            d0 = (own[s] - paths[s, j]) * scale
            v = ((own[s + 1] - own[s]) - (paths[s + 1, j] - paths[s, j])) * scale
            if min_distance_during_move(d0, v) < 1.0 - 1e-9:
                return False
    return True


@pytest.mark.parametrize("dim, reach", [(2, 1), (3, 1), (2, 2)])
def test_the_local_separation_check_agrees_with_all_pairs(dim, reach):
    """robot_clear tests only the (step, robot) pairs a step's moves can bring near; it must say what testing
    every pair says, on crowded random walks where both answers occur (moves of up to ``reach`` cells per axis,
    as ``mrf.order`` > 2 makes them)."""
    rng = np.random.default_rng(dim + 10 * reach)
    scale = np.ones(dim) if dim == 2 else np.array([1.0, 1.0, 0.5])
    answers = []
    for _ in range(600):
        N, T = 7, int(rng.integers(2, 9))  # short spans too: a pair that meets only in the span's last step
        steps = rng.integers(-reach, reach + 1, size=(T, N, dim)) * (rng.random((T, N, 1)) < 0.7)
        paths = np.concatenate([rng.integers(0, 5, size=(1, N, dim)), steps]).cumsum(axis=0)
        robot = int(rng.integers(N))
        first, last = sorted(int(v) for v in rng.choice(T + 1, size=2, replace=False))
        own = paths[:, robot].copy()  # another walk from the same cell, as a merge makes one
        own[first + 1:] = own[first] + (rng.integers(-reach, reach + 1, size=(T - first, dim))
                                         * (rng.random((T - first, 1)) < 0.7)).cumsum(axis=0)
        want = _clear_all_pairs(paths, robot, first, last, scale, own)
        assert robot_clear(paths, robot, first, last, scale, own) == want
        answers.append(want)
    assert 50 < sum(answers) < 550


def _walks(rng: np.random.Generator, n: int, steps: int, dim: int, reach: int, box: int) -> np.ndarray:
    """(steps + 1, n, dim) random walks from a box of side ``box``: moves of up to ``reach`` cells per axis, and
    waits of one to four steps between runs (so merges move robots by several cells), crowded so robots meet."""
    moving = np.ones((steps, n), dtype=bool)
    for i in range(n):
        t = int(rng.integers(0, 4))
        while t < steps:
            w = int(rng.integers(1, 5))
            moving[t:t + w, i] = False
            t += w + int(rng.integers(1, 6))
    moves = rng.integers(-reach, reach + 1, size=(steps, n, dim)) * moving[..., None]
    return np.concatenate([rng.integers(0, box, size=(1, n, dim)), moves]).cumsum(axis=0)


@pytest.mark.parametrize("dim", [2, 3])
def test_the_cell_index_finds_the_robots_in_a_box(dim):
    """CellIndex.near against every robot: all robots whose x and y lie within the reach (scaled) at the step are
    found, and none farther than a hair beyond it; after moves of robots, as a rebuilt index would."""
    from mrfswarm.discrete.merge_waits import CellIndex

    rng = np.random.default_rng(dim)
    paths = _walks(rng, 50, 20, dim, 2, 12)
    scale = np.array([0.5, 1.0, 0.25])[:dim]  # not 1 on x or y either: the index divides by it
    index = CellIndex(paths)
    for _ in range(100):
        robot, t0 = int(rng.integers(50)), int(rng.integers(20))
        new = paths[:, robot].copy()  # the robot's cells re-timed: a wait moved from t0 to the end
        new[t0:-1] = paths[t0 + 1:, robot]
        index.move(robot, paths[:, robot], new)
        paths[:, robot] = new
        np.testing.assert_array_equal(index.keys % 50, CellIndex(paths).keys % 50)  # each step's robots in order
        steps = rng.integers(0, 21, size=6)
        centre = rng.uniform(-2, 14, size=(6, dim)) * scale
        reach = rng.choice([0.5, 1.0, 2.0, 3.0 + 1e-9], size=6)
        q, j = index.near(steps, centre, reach, scale)
        gap = np.abs(paths[steps][..., :2] * scale[:2] - centre[:, None, :2]).max(axis=2)  # (6, N)
        found = np.zeros_like(gap, dtype=bool)
        found[q, j] = True
        assert len(q) == found.sum()  # each robot once
        assert np.all(found[gap <= reach[:, None]]) and not np.any(found[gap > reach[:, None] + 1e-5])


@pytest.mark.parametrize("dim, downwash, reach", [(2, 1.0, 1), (2, 1.0, 2), (3, 2.0, 1), (3, 3.0, 2)])
def test_the_cell_index_finds_every_robot_that_matters(dim, downwash, reach):
    """With a CellIndex, robot_clear looks only at the robots whose cells lie near the robot's at each step, and
    merge_waits tests the first blocks of a robot's tries at once; each must answer as testing every pair does (the
    first blocks: on their steps), on crowds of robots (downwash-scaled in 3-D) whose walks pass each other."""
    from mrfswarm.discrete.merge_waits import BLOCK, CellIndex, _first_blocks_clear
    from mrfswarm.geometry import downwash_scale

    rng = np.random.default_rng(7 * dim + reach)
    scale = downwash_scale(dim, downwash)
    answers, firsts = [], []
    for _ in range(150):
        T = int(rng.integers(2, 16))
        paths = _walks(rng, 40, T, dim, reach, 9)
        index = CellIndex(paths)
        largest = float(np.abs(np.diff(paths, axis=0)).max())
        robot = int(rng.integers(40))
        tries = []
        for _ in range(4):
            first, last = sorted(int(v) for v in rng.choice(T + 1, size=2, replace=False))
            own = paths[:, robot].copy()  # another walk from the same cell, as a merge makes one
            own[first + 1:] = own[first] + (rng.integers(-reach, reach + 1, size=(T - first, dim))
                                             * (rng.random((T - first, 1)) < 0.7)).cumsum(axis=0)
            want = _clear_all_pairs(paths, robot, first, last, scale, own)
            assert robot_clear(paths, robot, first, last, scale, own, largest, index) == want
            assert robot_clear(paths, robot, first, last, scale, own, largest) == want
            answers.append(want)
            tries.append((own, first, last))
        got = _first_blocks_clear(paths, robot, tries, scale, largest, index)
        for ok, (own, first, last) in zip(got, tries):
            assert ok == _clear_all_pairs(paths, robot, first, min(first + BLOCK, last), scale, own)
            firsts.append(ok)
    assert 0.1 < np.mean(answers) < 0.9 and 0.1 < np.mean(firsts) < 0.9


@pytest.mark.parametrize("dim, downwash", [(2, 1.0), (3, 2.0)])
@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("model", [False, True], ids=["every-safe-merge", "flight-model"])
def test_merging_with_the_index_is_merging_with_all_pairs(dim, downwash, seed, model, monkeypatch):
    """merge_waits keeps a CellIndex of the plan as it merges (and each step's largest needs, with a flight model)
    and tests the first blocks of a robot's tries at once: its paths and count are those the all-pairs check gives,
    merge for merge."""
    import mrfswarm.discrete.merge_waits as mw
    from mrfswarm.continuous.time_grid import FlightModel

    rng = np.random.default_rng(seed)
    paths = _walks(rng, 30, 24, dim, 1, 7)
    flight = FlightModel(1.0, 1.85, 2.0, 0.5) if model else None
    fast, n_fast = mw.merge_waits(paths, downwash, flight)

    def all_pairs(paths, robot, first, last, scale, own, largest_move=None, index=None):
        return _clear_all_pairs(paths, robot, first, last, scale, own)

    # and no test of the first blocks ahead: a try it refuses wrongly would be refused by both
    monkeypatch.setattr(mw, "_first_blocks_clear", lambda paths, robot, tries, *a: np.ones(len(tries), dtype=bool))
    monkeypatch.setattr(mw, "robot_clear", all_pairs)
    slow, n_slow = mw.merge_waits(paths, downwash, flight)
    monkeypatch.setattr(mw, "robot_clear", lambda *a: True)
    assert n_fast == n_slow and 0 < n_slow < mw.merge_waits(paths, downwash, flight)[1]  # merges made and refused
    np.testing.assert_array_equal(fast, slow)


def test_each_steps_largest_without_a_robot_follows_its_changes():
    """_Steps ranks again only the steps where a robot's values change; the largest over the others must stay the
    direct maximum (ties included: values on a coarse grid)."""
    from mrfswarm.discrete.merge_waits import _Steps

    rng = np.random.default_rng(0)
    needs, lengths = rng.integers(0, 4, size=(2, 30, 6)).astype(float)
    steps = _Steps(needs.copy(), lengths.copy())
    for _ in range(200):
        robot = int(rng.integers(6))
        new_needs, new_lengths = needs[:, robot].copy(), lengths[:, robot].copy()
        rows = rng.random(30) < 0.2
        new_needs[rows], new_lengths[rows] = rng.integers(0, 4, size=(2, int(rows.sum())))
        needs[:, robot], lengths[:, robot] = new_needs, new_lengths
        steps.set(robot, new_needs, new_lengths)
        for r in range(6):
            others = np.delete(np.arange(6), r)
            want = needs[:, others].max(axis=1), lengths[:, others].max(axis=1)
            for got, w in zip(steps.without(r), want):
                np.testing.assert_array_equal(got, w)
