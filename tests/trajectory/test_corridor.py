"""Corridor samples, tubes around reference motions, time laws, and corridor-constrained solves."""

import numpy as np
import pytest

import solvers.qp
from mrfswarm.trajectory import (
    TIME_LAWS,
    Corridor,
    PolylineReference,
    corridor_sample_taus,
    corridor_sample_times,
    segment_reference,
    solve_min_snap,
    time_law,
    tube_corridor,
)
from solvers.errors import InvalidProblem


def test_corridor_sample_times_are_interior_and_global():
    np.testing.assert_allclose(corridor_sample_taus(3), [0.25, 0.5, 0.75])
    t = corridor_sample_times([1.0, 2.0], 3, t0=10.0)
    np.testing.assert_allclose(t, [[10.25, 10.5, 10.75], [11.5, 12.0, 12.5]])


def test_the_corridor_sample_times_have_one_name():
    """No alias: the old general-sounding names are gone from the package."""
    import mrfswarm.trajectory
    import mrfswarm.trajectory.corridor

    for module in (mrfswarm.trajectory, mrfswarm.trajectory.corridor):
        assert not hasattr(module, "sample_times") and not hasattr(module, "sample_taus")
    assert {"corridor_sample_times", "corridor_sample_taus"} <= set(mrfswarm.trajectory.__all__)
    with pytest.raises(InvalidProblem, match="samples_per_piece must be >= 0, got -1"):
        corridor_sample_times([1.0], -1)


@pytest.mark.parametrize("name", list(TIME_LAWS))
def test_time_laws_go_from_0_to_1_monotonically(name):
    s = time_law(name)
    tau = np.linspace(0, 1, 201)
    v = s(tau)
    assert v[0] == 0 and v[-1] == pytest.approx(1.0) and np.all(np.diff(v) >= -1e-15)
    assert s(-1.0) == 0 and s(2.0) == pytest.approx(1.0)


def test_smooth_laws_are_at_rest_at_the_ends():
    for name, order in (("quintic", 2), ("smooth", 3)):
        c = np.array(TIME_LAWS[name])
        for r in range(1, order + 1):
            d = np.polynomial.polynomial.polyder(c, r)
            assert np.polynomial.polynomial.polyval(0.0, d) == 0
            assert np.polynomial.polynomial.polyval(1.0, d) == pytest.approx(0.0, abs=1e-12)


def test_unknown_time_law():
    with pytest.raises(InvalidProblem, match="known: linear"):
        time_law("cubic-ish")


def test_polyline_reference_positions():
    ref = PolylineReference([[0, 0], [2, 0], [2, 4]], [0.0, 1.0, 3.0])
    np.testing.assert_allclose(ref(np.array([-1.0, 0.0, 0.5, 1.0, 2.0, 3.0, 9.0])),
                               [[0, 0], [0, 0], [1, 0], [2, 0], [2, 2], [2, 4], [2, 4]])
    seg = segment_reference([0, 0], [1, 1], 1.0, 2.0, law="smooth")
    np.testing.assert_allclose(seg(1.5), [0.5, 0.5])
    with pytest.raises(InvalidProblem, match="increasing"):
        PolylineReference([[0, 0], [1, 1]], [1.0, 1.0])


def test_tube_from_callable_scalar_callable_and_array_agree():
    T = np.array([1.0, 0.5])
    ref = segment_reference([0.0, 0.0], [3.0, 1.0], 0.0, 1.5)
    a = tube_corridor(ref, T, 4, 0.2)
    b = tube_corridor(lambda t: np.array([2.0 * float(t), float(t) * 2 / 3]), T, 4, 0.2)  # scalar-only callable
    c = tube_corridor(ref(corridor_sample_times(T, 4)), T, 4, 0.2)
    for other in (b, c):
        np.testing.assert_allclose(other.lower, a.lower)
        np.testing.assert_allclose(other.upper, a.upper)
    np.testing.assert_allclose(a.upper - a.lower, 0.4)
    with pytest.raises(InvalidProblem, match="half-width"):
        tube_corridor(ref, T, 4, 0.0)


def test_corridor_validation():
    with pytest.raises(InvalidProblem, match="lower bound exceeds"):
        Corridor(np.ones((1, 2, 2)), np.zeros((1, 2, 2)))
    with pytest.raises(InvalidProblem, match="shape"):
        Corridor(np.ones((1, 2)), np.ones((1, 2)))


def test_box_corridor_holds_at_samples_with_infinite_sides():
    # keep y >= -0.05 at every sample (the free solution dips below), x unconstrained
    W = np.array([[0.0, 0.0], [1.0, 0.0], [1.5, 1.0], [3.0, 0.0]])
    T = np.ones(3)
    K = 8
    free = solve_min_snap(W, T).trajectory
    lo = np.full((3, K, 2), -np.inf)
    hi = np.full((3, K, 2), np.inf)
    lo[:, :, 1] = -0.05
    c = Corridor(lo, hi)
    assert c.violation(free) > 0.01
    res = solve_min_snap(W, T, corridor=c, backend=solvers.qp.DEFAULT_BACKEND)
    assert c.violation(res.trajectory) < 1e-6
    y = res.trajectory(corridor_sample_times(T, K))[..., 1]
    assert y.min() == pytest.approx(-0.05, abs=1e-5)  # the bound is tight somewhere
    np.testing.assert_allclose(res.trajectory(res.trajectory.knots), W, atol=1e-6)


def test_tube_on_a_common_time_grid_with_offset_start():
    # a later receding-horizon window: pieces start at t0 = 4 on the swarm's grid
    grid_t = np.arange(0.0, 9.0)
    grid_p = np.c_[np.arange(9.0), np.zeros(9)]
    ref = PolylineReference(grid_p, grid_t, law="smooth")
    W = grid_p[4:8]
    T = np.ones(3)
    c = tube_corridor(ref, T, 5, 0.05, t0=4.0)
    np.testing.assert_allclose((c.lower + c.upper)[0, :, 0] / 2, ref(4.0 + corridor_sample_times(T, 5)[0])[:, 0])
    res = solve_min_snap(W, T, corridor=c, backend=solvers.qp.DEFAULT_BACKEND)
    assert c.violation(res.trajectory) < 1e-6
