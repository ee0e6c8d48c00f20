"""Straightening a robot's path: the same steps, no longer moves, a shorter way (``mrf.straighten``)."""

from __future__ import annotations

import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

from mrfswarm.config import apply_overrides, from_dict
from mrfswarm.discrete.safety import discrete_violations
from mrfswarm.discrete.straighten import shortest_lengths, straighten
from mrfswarm.pipeline import plan

EXPERIMENTS = Path(__file__).resolve().parents[2] / "experiments"


def lengths(P: np.ndarray) -> np.ndarray:
    return np.linalg.norm(np.diff(P, axis=0), axis=-1)


def test_shortest_lengths_are_the_octile_distances():
    np.testing.assert_allclose(shortest_lengths(np.array([[4, 0], [3, -1], [0, 0], [-2, 2]])),
                               [4, 2 + np.sqrt(2), 0, 2 * np.sqrt(2)])
    np.testing.assert_allclose(shortest_lengths(np.array([[3, 2, 1], [0, 0, -2]])),
                               [1 + np.sqrt(2) + np.sqrt(3), 2])


def test_a_lone_robots_zigzag_becomes_a_straight_run():
    col = np.array([[0, 1], [1, 2], [2, 1], [3, 2], [4, 1]])
    out, done = straighten(col[:, None], np.ones((6, 4), dtype=bool))
    assert done >= 1
    np.testing.assert_array_equal(out[:, 0], [[x, 1] for x in range(5)])


def test_a_window_with_a_longer_move_is_kept_and_the_rest_straightened():
    """mrf.order >= 4 moves a robot two cells along an axis in one step; the search (unit moves) then looked for a
    way to a cell beyond its box and crashed (mrf.order = 5 on every map with straightening on). Such a window is
    kept as it is; a zigzag of unit moves elsewhere in the path is still straightened. Random paths of order-5
    moves: no error, the ends kept, no move longer."""
    col = np.array([[0, 1], [2, 2], [3, 1], [4, 2], [5, 1], [6, 2], [7, 1], [8, 2], [9, 1], [10, 2], [11, 1],
                    [12, 2], [13, 1], [14, 2]])
    out, done = straighten(col[:, None], np.ones((16, 4), dtype=bool))
    assert done >= 1 and np.array_equal(out[:2, 0], col[:2])
    assert lengths(out).sum() < lengths(col[:, None]).sum() - 1e-6
    rng = np.random.default_rng(0)
    moves = np.array([(dx, dy) for dx in range(-2, 3) for dy in range(-2, 3) if dx * dx + dy * dy <= 5])
    for _ in range(100):
        col = np.concatenate([[[12, 12]], 12 + np.cumsum(moves[rng.integers(0, len(moves), 10)], axis=0)])[:, None]
        out, _ = straighten(col, np.ones((30, 30), dtype=bool))
        assert np.array_equal(out[[0, -1]], col[[0, -1]]) and np.all(lengths(out) <= lengths(col) + 1e-9)


def test_a_plan_of_order_5_is_straightened_without_error():
    data = tomllib.loads((EXPERIMENTS / "arena.toml").read_text())
    cfg = from_dict(apply_overrides(data, ["simulation.enabled=false", "smoothing.enabled=false", "mrf.order=5"]),
                    EXPERIMENTS)
    assert cfg.mrf.straighten
    r = plan(cfg, progress=False)
    assert r.metrics.reached_goal and all(robot.at_goal for robot in r.robots())


def test_a_wait_stays_a_wait_and_no_move_grows():
    # diagonal, wait, diagonal back: the way is shorter as straight, wait, straight, the wait in its step
    col = np.array([[0, 1], [1, 2], [1, 2], [2, 1], [3, 1]])
    out, done = straighten(col[:, None], np.ones((5, 4), dtype=bool))
    assert done == 1
    np.testing.assert_array_equal(out[:, 0], [[0, 1], [1, 1], [1, 1], [2, 1], [3, 1]])
    # straight, diagonal, diagonal, diagonal: the shortest way has one diagonal, in a step that had one
    col = np.array([[0, 0], [1, 0], [2, 1], [3, 0], [4, 1]])
    out, done = straighten(col[:, None], np.ones((5, 2), dtype=bool))
    assert done == 1
    assert lengths(out).sum() == pytest.approx(3 + np.sqrt(2))
    assert np.all(lengths(out) <= lengths(col[:, None]) + 1e-12)


def around_an_obstacle() -> tuple[np.ndarray, np.ndarray]:
    """A robot arcs (0, 0) -> (1, 1) -> (2, 2) -> (3, 1) -> (4, 0) over an obstacle at (2, 0)."""
    free = np.ones((5, 3), dtype=bool)
    free[2, 0] = False
    return np.array([[0, 0], [1, 1], [2, 2], [3, 1], [4, 0]])[:, None], free


def test_an_obstacle_is_gone_around():
    paths, free = around_an_obstacle()
    assert discrete_violations(paths, free) == []
    out, done = straighten(paths, free)
    assert done >= 1
    # the straight run (1, 1) -> (3, 1) keeps half a cell from (2, 0); the diagonals at the ends cut no corner
    np.testing.assert_array_equal(out[:, 0], [[0, 0], [1, 1], [2, 1], [3, 1], [4, 0]])
    assert discrete_violations(out, free) == []


def test_the_clear_move_table_is_the_guard_for_obstacles(monkeypatch):
    """With every move counted clear, the robot goes straight through the obstacle."""
    import mrfswarm.discrete.straighten as st

    paths, free = around_an_obstacle()
    monkeypatch.setattr(st, "clear_moves", lambda f: np.ones((*f.shape, 9), dtype=bool))
    monkeypatch.setattr(st, "_LAST_INTO", [])  # not the last map's table
    out, done = st.straighten(paths, free)
    assert done >= 1
    assert discrete_violations(out, free) != []


def test_the_clear_move_table_is_computed_once_per_map(monkeypatch):
    """The table is of the whole map (8.4 s on 2000 x 2000): kept for the next plan on the same map ("auto" plans up
    to three), computed again for another map."""
    import mrfswarm.discrete.straighten as st

    monkeypatch.setattr(st, "_LAST_INTO", [])
    calls: list[tuple] = []
    clear_moves = st.clear_moves
    monkeypatch.setattr(st, "clear_moves", lambda f: calls.append(f.shape) or clear_moves(f))
    paths, free = around_an_obstacle()
    first, _ = st.straighten(paths, free)
    again, _ = st.straighten(paths, free.copy())
    np.testing.assert_array_equal(first, again)
    assert len(calls) == 1
    other = free.copy()
    other[0, -1] = not other[0, -1]
    table = st._clear_into_of(other)
    assert len(calls) == 2 and not np.array_equal(table, st._clear_into_of(free))
    assert not table.flags.writeable  # shared: no plan may write into it


def beside_a_neighbour() -> np.ndarray:
    """Robot 0 arcs (0, 2) -> (1, 3) -> (2, 3) -> (3, 3) -> (4, 2) over robot 1, waiting on the straight way at (2, 2)."""
    r0 = [(0, 2), (1, 3), (2, 3), (3, 3), (4, 2)]
    r1 = [(2, 2)] * 5
    return np.array([r0, r1]).transpose(1, 0, 2)


def test_a_neighbour_keeps_the_zigzag():
    paths, free = beside_a_neighbour(), np.ones((5, 4), dtype=bool)
    assert discrete_violations(paths, free) == []
    out, done = straighten(paths, free)
    assert done == 0
    np.testing.assert_array_equal(out, paths)


def test_the_separation_check_is_the_guard_for_neighbours(monkeypatch):
    import mrfswarm.discrete.straighten as st

    monkeypatch.setattr(st, "robot_clear", lambda *a: True)
    out, done = st.straighten(beside_a_neighbour(), np.ones((5, 4), dtype=bool))
    assert done == 1
    assert discrete_violations(out, np.ones((5, 4), dtype=bool)) != []


def test_downwash_counts_in_the_check():
    # robot 0 zigzags sideways under robot 1, which hovers 3 voxels above the straight way's middle voxel
    # (1, 0, 1): apart in the plain metric, 3 / 4 of a voxel with c = 4
    r0 = np.array([[0, 0, 1], [1, 1, 1], [2, 0, 1]])
    r1 = np.array([[1, 0, 4], [1, 0, 4], [1, 0, 4]])
    paths, free = np.stack([r0, r1], axis=1), np.ones((3, 2, 5), dtype=bool)
    assert discrete_violations(paths, free, downwash=4.0) == []
    assert straighten(paths, free, downwash=1.0)[1] == 1
    out, done = straighten(paths, free, downwash=4.0)
    assert done == 0
    np.testing.assert_array_equal(out, paths)


@pytest.mark.parametrize("case", ["doorway", "clutter40"])
def test_a_plan_keeps_its_ends_steps_waits_and_invariant_and_no_move_grows(case):
    sys.path.insert(0, str(EXPERIMENTS / "bench"))
    import flight_quality as fq

    data, base = fq.case_config(case)
    data = apply_overrides(data, ["smoothing.enabled=false", "simulation.enabled=false", "mrf.straighten=false"])
    r = plan(from_dict(data, base), progress=False)
    P, free = r.discrete.paths, r.scenario.grid.free
    Q, done = straighten(P, free)
    assert done >= 3
    assert Q.shape == P.shape
    np.testing.assert_array_equal(Q[[0, -1]], P[[0, -1]])
    assert np.all(lengths(Q) <= lengths(P) + 1e-9)
    np.testing.assert_array_equal(lengths(Q) > 0, lengths(P) > 0)
    assert lengths(Q).sum() < lengths(P).sum() - 1.0
    assert discrete_violations(Q, free) == []


def test_the_default_run_straightens_and_says_so():
    sys.path.insert(0, str(EXPERIMENTS / "bench"))
    import flight_quality as fq

    data, base = fq.case_config("doorway")
    on = plan(from_dict(apply_overrides(data, ["smoothing.enabled=false", "simulation.enabled=false"]), base),
              progress=False)
    off = plan(from_dict(apply_overrides(data, ["smoothing.enabled=false", "simulation.enabled=false",
                                                "mrf.straighten=false"]), base), progress=False)
    assert on.discrete.straightened > 0 and off.discrete.straightened == 0
    assert on.summary()["straightened"] == on.discrete.straightened
    assert lengths(on.discrete.paths).sum() < lengths(off.discrete.paths).sum()


def test_the_paper_configs_keep_the_mrfs_cells():
    for name in ("corridor", "blocks", "free10", "swarm_size"):
        data = tomllib.loads((EXPERIMENTS / f"{name}.toml").read_text())
        assert data["mrf"]["straighten"] is False, name


def random_walks(seed: int, robots: int = 4, steps: int = 40) -> tuple[np.ndarray, np.ndarray]:
    """Robots wandering right in bands of their own among random obstacles: moves of every kind, waits, zigzags."""
    rng = np.random.default_rng(seed)
    free = rng.random((steps + 2, 6 * robots)) > 0.12
    cols = []
    for i in range(robots):
        cell = np.array([0, 6 * i + 2])
        free[tuple(cell)] = True
        col = [cell.copy()]
        for _ in range(steps):
            options = [m for m in ([0, 0], [1, -1], [1, 0], [1, 1], [0, 1], [0, -1])
                       if 6 * i <= cell[1] + m[1] < 6 * i + 5 and free[tuple(cell + m)]]
            cell = cell + np.array(options[rng.integers(len(options))])
            col.append(cell.copy())
        cols.append(col)
    return np.array(cols).transpose(1, 0, 2), free


@pytest.mark.parametrize("seed", range(6))
def test_the_free_map_filter_skips_only_windows_without_a_shorter_way(seed, monkeypatch):
    # the table of windows worth searching (_slack) against searching every window: the same plan
    import mrfswarm.discrete.straighten as st

    paths, free = random_walks(seed)
    slack, _ = st._slack(paths, st.WINDOW)
    own = lengths(paths)
    checked = 0
    for k in range(2, st.WINDOW + 1):  # the table against each window's own search
        for s in range(len(paths) - k):
            for i in range(paths.shape[1]):
                offset = tuple(sorted(np.abs(paths[s + k, i] - paths[s, i]).tolist()))
                caps = tuple(sorted(np.round(own[s:s + k, i], 9).tolist()))
                assert slack[s, i, k] == (own[s:s + k, i].sum() > st._unobstructed_sorted(offset, caps) + 1e-6)
                checked += slack[s, i, k]
    assert checked > 50
    fast, done = straighten(paths, free)
    assert done > 0

    def every_window(P, window):
        slack, order = real(P, window)
        for k in range(2, window + 1):
            slack[:len(P) - k, :, k] = True  # every window s..s + k within the plan
        return slack, order

    real = st._slack
    monkeypatch.setattr(st, "_slack", every_window)
    slow, done_slow = straighten(paths, free)
    assert done_slow == done
    np.testing.assert_array_equal(fast, slow)


def cheapest_in_order(ways: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The reference: the rows (moves) in order, each replacing the best so far where shorter by more than 1e-9."""
    best, row = np.full(ways.shape[1], np.inf), np.full(ways.shape[1], -1)
    for j, way in enumerate(ways):
        better = way < best - 1e-9
        best, row = np.where(better, way, best), np.where(better, j, row)
    return best, row


@pytest.mark.parametrize("band", [False, True], ids=["apart", "within-the-tolerance"])
def test_the_cheapest_move_is_the_one_taking_the_moves_in_order_keeps(band):
    """_cheapest picks at once the value and row the rule in order leaves: on lengths of ways equal up to rounding
    (a few ulps apart, in any order) or apart, and no way at all; and, where values lie within the tolerance of
    each other without being equal, by taking the rows in order."""
    import mrfswarm.discrete.straighten as st

    rng = np.random.default_rng(int(band))
    values = np.array([1.0, 1 + np.sqrt(2), 2 * np.sqrt(2), 3.0, 2 + np.sqrt(3), np.inf])
    for _ in range(300):
        ways = rng.choice(values, size=(int(rng.integers(0, 10)), int(rng.integers(0, 30))))
        ways = np.where(rng.random(ways.shape) < 0.3, np.nextafter(ways, np.inf), ways)
        ways = np.where(rng.random(ways.shape) < 0.3, np.nextafter(ways, 0.0), ways)
        if band:
            ways = ways + rng.choice([0.0, 6e-10, 1e-9, 1.5e-9, 3e-9], size=ways.shape)
        best, row = st._cheapest(ways)
        want_best, want_row = cheapest_in_order(ways)
        np.testing.assert_array_equal(best, want_best)
        np.testing.assert_array_equal(row, want_row)


class SearchMoveByMove:
    """The reference: the shortest ways' program of :class:`~mrfswarm.discrete.straighten._Search` with each move in
    turn into the whole box at every step, from :func:`~mrfswarm.discrete.straighten.clear_moves`' table."""

    def __init__(self, a: np.ndarray, own: np.ndarray, clear: np.ndarray, ends: list) -> None:
        from mrfswarm.discrete.straighten import unit_moves

        self.moves, lengths = unit_moves(len(a))
        K = len(own)
        self.lo = np.maximum(np.maximum(a - K, 0), np.min([b - k for k, b in ends], axis=0))
        hi = np.minimum(np.minimum(a + K, np.array(clear.shape[:-1]) - 1), np.max([b + k for k, b in ends], axis=0))
        box = tuple(int(v) for v in hi - self.lo + 1)
        local = clear[tuple(slice(int(x), int(y) + 1) for x, y in zip(self.lo, hi))]
        cost = np.full(box, np.inf)
        cost[tuple(a - self.lo)] = 0.0
        self.costs, self.came = [cost], []
        for t in range(K):
            new, how = np.full(box, np.inf), np.full(box, -1)
            for j, m in enumerate(self.moves.tolist()):
                if not (lengths[j] <= own[t] + 1e-9 and (lengths[j] > 0) == (own[t] > 0)):
                    continue
                src = tuple(slice(max(0, -v), n - max(0, v)) for v, n in zip(m, box))
                dst = tuple(slice(max(0, v), n - max(0, -v)) for v, n in zip(m, box))
                val = np.where(local[(*src, j)], cost[src] + lengths[j], np.inf)
                better = val < new[dst] - 1e-9
                new[dst] = np.where(better, val, new[dst])
                how[dst] = np.where(better, j, how[dst])
            cost = new
            self.costs.append(cost)
            self.came.append(how)

    def cost_and_way(self, k: int, b: np.ndarray) -> tuple[float, list]:
        cell = np.asarray(b) - self.lo
        if np.any(cell < 0) or np.any(cell >= self.costs[0].shape) or not np.isfinite(self.costs[k][tuple(cell)]):
            return np.inf, []
        way = [cell + self.lo]
        for t in range(k, 0, -1):
            cell = cell - self.moves[self.came[t - 1][tuple(cell)]]
            way.append(cell + self.lo)
        return float(self.costs[k][tuple(b - self.lo)]), way[::-1]


@pytest.mark.parametrize("dim", [2, 3])
def test_the_search_finds_the_ways_the_move_by_move_program_finds(dim):
    """_Search relaxes all moves at once and only into the cells a way read can pass; the lengths and cells of the
    ways to its ends must be those of relaxing each move in turn into the whole box, ties and all, on maps with
    obstacles (near the map's edges too), with capped steps and waits, and ends reachable or not."""
    from mrfswarm.discrete.straighten import _Search, clear_into, clear_moves, unit_moves

    rng = np.random.default_rng(dim)
    shape = (16, 16) if dim == 2 else (10, 10, 6)
    moves, lengths = unit_moves(dim)
    found = 0
    for _ in range(60):
        free = rng.random(shape) > 0.2
        clear = clear_moves(free)
        into = clear_into(clear)
        for _ in range(5):
            a = np.array([int(rng.integers(n)) for n in shape])
            K = int(rng.integers(2, 9))
            own = rng.choice(np.unique(lengths), size=K)  # the caps, waits (0) among them
            walk = a + np.cumsum([moves[rng.choice(np.flatnonzero(np.abs(lengths - c) < 1e-9))] for c in own], axis=0)
            ks = sorted({K, *rng.integers(1, K + 1, size=2).tolist()}, reverse=True)
            ends = [(k, walk[k - 1] if rng.random() < 0.8 else a + rng.integers(-k, k + 1, size=dim)) for k in ks]
            fast = _Search(a, own, into, ends)
            slow = SearchMoveByMove(a, own, clear, ends)
            for k, b in ends:
                cost, way = slow.cost_and_way(k, b)
                assert fast.cost(k, b) == cost
                if np.isfinite(cost):
                    np.testing.assert_array_equal(fast.way(k, b), way)
                    found += 1
    assert found > 200
