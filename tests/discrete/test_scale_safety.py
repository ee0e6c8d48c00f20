"""The indexed discrete safety check equals the all-pairs one (its oracle) on random swarms."""

import numpy as np
import pytest

from mrfswarm.discrete.motion import min_distance_during_move, segments_clear, stencil, step_min_separation
from mrfswarm.discrete.safety import discrete_violations, discrete_violations_brute_force
from mrfswarm.geometry import segment_clear
from support.swarms import random_start


def random_plan(rng, n, steps, W=30, H=30, order=2, p_bad=0.0):
    """Robots on distinct cells moving by stencil offsets; with ``p_bad`` some moves ignore every rule."""
    free, pos = random_start(rng, n, W, H, 0.12)
    off = stencil(order)
    paths = [pos]
    for _ in range(steps):
        mv = off[rng.integers(0, len(off), n)]
        new = pos + mv
        bad = rng.random(n) < p_bad
        keep = ~bad & ~((new >= [0, 0]) & (new < [W, H])).all(axis=1)
        new[keep] = pos[keep]
        paths.append(new)
        pos = new
    return np.stack(paths), free


@pytest.mark.parametrize("seed", range(12))
def test_indexed_check_equals_all_pairs(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 60))
    order = int(rng.choice([1, 2, 4, 8]))
    paths, free = random_plan(rng, n, 6, order=order, p_bad=float(rng.choice([0.0, 0.05, 0.3])))
    for limit in (10, 10**6):
        assert discrete_violations(paths, free, limit) == discrete_violations_brute_force(paths, free, limit)


def test_pairs_exactly_at_the_query_radius():
    """Head-on pairs that start exactly 1 + 2 s apart touch one cell at the end: safe, in both checks;
    one cell further inward and they collide, also in both."""
    free = np.ones((40, 12), bool)
    for s in (1, 2, 3):
        p0 = np.array([[5, 5], [5 + 1 + 2 * s, 5], [30, 5], [30, 6]])
        p1 = p0 + [[s, 0], [-s, 0], [0, 0], [0, 0]]
        ok = np.stack([p0, p1])
        assert discrete_violations(ok, free) == discrete_violations_brute_force(ok, free) == []
        p0b = p0.copy()
        p0b[1, 0] -= 1
        p1b = p0b + [[s, 0], [-s, 0], [0, 0], [0, 0]]
        p1b[1] += [0, 1]  # no shared end cell: only the crossing is wrong
        bad = np.stack([p0b, p1b])
        found = discrete_violations(bad, free)
        assert found == discrete_violations_brute_force(bad, free)
        assert any("(0, 1)" in v and "close while moving" in v for v in found)


def test_step_min_separation_finds_a_pair_exactly_at_its_radius():
    """The closest approach can belong to a pair that starts exactly d_nn + 2 s apart (a tie)."""
    p0 = np.array([[0.0, 0.0], [1.0, 0.0], [10.0, 0.0], [13.0, 0.0]])
    p1 = p0 + [[0, 0], [0, 0], [1, 0], [-1, 0]]
    d, _ = step_min_separation(p0, p1)
    iu, ju = np.triu_indices(4, 1)
    brute = min_distance_during_move(p0[iu] - p0[ju], (p1[iu] - p0[iu]) - (p1[ju] - p0[ju]))
    assert d == pytest.approx(brute.min()) == 1.0
    p0[3, 0] = 12.5  # inward: now the moving pair is the closest alone
    p1 = p0 + [[0, 0], [0, 0], [1, 0], [-1, 0]]
    assert step_min_separation(p0, p1) == (pytest.approx(0.5), (2, 3))


@pytest.mark.parametrize("seed", range(4))
def test_segments_clear_equals_segment_clear(seed):
    rng = np.random.default_rng(seed)
    free = rng.random((20, 20)) > 0.25
    a = rng.integers(-2, 22, (300, 2))
    b = a + rng.integers(-4, 5, (300, 2))
    got = segments_clear(free, a, b)
    assert got.tolist() == [segment_clear(free, p, q) for p, q in zip(a, b)]
    assert got.any() and not got.all()


def test_findings_name_cells_as_plain_numbers():
    """A cell in a finding read "(np.int64(11), np.int64(11))" (NumPy 2's repr of a tuple of its integers), and
    paths without their axis of points ended in "'numpy.int64' object is not iterable" (a library tour)."""
    free = np.ones((10, 10), dtype=bool)
    free[4, 4] = False
    paths = np.array([[[0, 0], [2, 2]], [[11, 11], [4, 4]]])
    for check in (discrete_violations, discrete_violations_brute_force):
        assert check(paths, free)[:4] == ["step 1: robot 0 off the map at cell (11, 11)",
                                          "step 1: robot 1 in an occupied cell (4, 4)",
                                          "step 1: robot 0's move (0, 0) -> (11, 11) cuts an obstacle",
                                          "step 1: robot 1's move (2, 2) -> (4, 4) cuts an obstacle"]
    with pytest.raises(ValueError, match=r"^paths must have shape \(T \+ 1, N, 2\) .*got \(2, 2\)$"):
        discrete_violations(paths[:, :, 0], free)
