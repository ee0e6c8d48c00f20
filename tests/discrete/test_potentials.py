"""The paper's potentials: Morse minimum, parameter conditions, goal and obstacle fields."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import minimize_scalar

from mrfswarm.config import GoalPotentialConfig, ObstaclePotentialConfig, load_config
from mrfswarm.discrete.potentials import Morse, goal_distances, goal_field, obstacle_field, static_field
from mrfswarm.errors import ConfigError


def test_paper_values():
    m = Morse()
    assert m.d_min == pytest.approx(8.42, abs=0.005)
    assert m.raw(m.d_min) == pytest.approx(-0.274, abs=0.0005)
    assert m.zeta > abs(m.raw(m.d_min))


@st.composite
def morse_params(draw):
    a = draw(st.floats(0.1, 5.0))
    b = a * draw(st.floats(1.0, 3.0))
    k_r = draw(st.floats(0.5, 10.0))
    # b k_r / (a k_a) < 1  <=>  k_a > b k_r / a (which also gives k_a > k_r as b >= a)
    k_a = (b * k_r / a) * draw(st.floats(1.05, 4.0))
    return a, b, k_a, k_r


@settings(max_examples=60, deadline=None)
@given(morse_params())
def test_d_min_formula_is_the_numeric_minimum(p):
    m = Morse(*p)
    res = minimize_scalar(lambda d: float(m.raw(d)), bounds=(1e-6, 50 * m.k_a), method="bounded",
                          options={"xatol": 1e-10})
    assert m.d_min == pytest.approx(res.x, rel=1e-4, abs=1e-6)
    # the minimum is a minimum: the derivative changes sign there
    h = 1e-4 * max(1.0, m.d_min)
    assert m.raw(m.d_min - h) > m.raw(m.d_min) < m.raw(m.d_min + h)
    d = np.linspace(0, 20 * m.k_a, 2001)
    assert np.all(m(d) > 0)


@pytest.mark.parametrize("kw, key", [
    (dict(a=0.9, b=0.7), "interaction.b"),
    (dict(k_a=4.0, k_r=14.0), "interaction.k_a"),
    (dict(a=0.7, b=0.9, k_a=5.0, k_r=4.0), "b \\* k_r / \\(a \\* k_a\\)"),
    (dict(a=-1.0), "interaction.a"),
    (dict(zeta=0.1), "interaction.zeta"),
])
def test_parameter_conditions_are_enforced(kw, key):
    with pytest.raises(ConfigError, match=key):
        Morse(**kw)
    # the same conditions when the config is loaded, before any planning
    with pytest.raises(ConfigError, match=key):
        load_config(None, [f"interaction.{k}={v}" for k, v in kw.items()])


def test_goal_field_values():
    """k_G counts cells: at 0.5 m cells, 5 cells (2.5 m) from the goal rho_G = a exp(5 / 20)."""
    g = goal_field((30, 20), np.array([10, 5]), 0.5, GoalPotentialConfig(a=3.0, k=20.0))
    assert g.shape == (30, 20)
    assert g[10, 5] == pytest.approx(3.0)
    assert g[13, 9] == pytest.approx(3.0 * math.exp(5 / 20.0))
    assert np.unravel_index(np.argmin(g), g.shape) == (10, 5)
    assert np.all(goal_field((4, 4), None, 1.0, GoalPotentialConfig()) == 0)


def test_obstacle_field_is_blurred_threshold():
    prob = np.zeros((21, 21))
    prob[10, 10] = 0.7  # occupied
    prob[3, 3] = 0.4  # below the paper's threshold: free
    f = obstacle_field(prob, ObstaclePotentialConfig(gamma=5.0, sigma=1.0))
    assert f.sum() == pytest.approx(5.0, rel=1e-6)  # the kernel is normalized
    assert f[3, 3] == pytest.approx(0.0, abs=1e-12)
    assert f[10, 10] == pytest.approx(5.0 / (2 * math.pi), rel=0.02)  # peak of a unit 2-D Gaussian
    assert f[11, 10] < f[10, 10] and f[11, 10] == pytest.approx(f[10, 11]) == pytest.approx(f[9, 10])
    raw = obstacle_field(prob, ObstaclePotentialConfig(gamma=5.0, sigma=0.0))
    assert raw[10, 10] == 5.0 and raw.sum() == 5.0


def test_static_field_is_the_sum():
    prob = np.zeros((12, 9))
    prob[4:6, 2:7] = 1.0
    goal = np.array([10, 4])
    oc = ObstaclePotentialConfig()
    euclid = GoalPotentialConfig(distance="euclidean")
    s = static_field(prob, goal, 1.0, euclid, oc)
    np.testing.assert_allclose(s, goal_field(prob.shape, goal, 1.0, euclid) + obstacle_field(prob, oc))
    geo = GoalPotentialConfig()  # the default
    d = goal_distances(prob, goal, 1.0, geo, oc)
    s = static_field(prob, goal, 1.0, geo, oc)
    free = prob < 0.5
    np.testing.assert_allclose(s[free], (goal_field(prob.shape, goal, 1.0, geo, d.field) + obstacle_field(prob, oc))[free])
    assert np.all(np.isinf(s[~free]))
    # behind the wall the geodesic field is higher than the straight-line one
    assert s[2, 4] > goal_field(prob.shape, goal, 1.0, euclid)[2, 4] + obstacle_field(prob, oc)[2, 4]


def _field_path_excess(occ: np.ndarray, goal: np.ndarray, obstacle: ObstaclePotentialConfig) -> float:
    """Mean length of the geodesic field's descent (next cell after next cell) over the shortest free path, from
    every cell more than 25 m from the goal."""
    d = goal_distances(occ.astype(float), goal, 1.0, GoalPotentialConfig(), obstacle)
    ratios = []
    for c in np.argwhere(np.isfinite(d.path) & (d.path > 25)):
        p, length = tuple(c), 0.0
        while d.path[p] > 0:
            q = tuple(d.next_cell[p])
            length += float(np.hypot(*np.subtract(q, p)))
            p = q
        ratios.append(length / d.path[tuple(c)])
    return float(np.mean(ratios))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_default_gamma_lets_the_field_pass_clutter_near_its_shortest_path(seed):
    """The geodesic field prices the obstacle potential a path climbs (k_G / a_G m per unit): with the paper's
    Gamma = 5 its descent through 10 % single-cell clutter is 4-6.5 % longer than the shortest path (the swarm weaves
    around single cells), with the default 2 at most 3 %."""
    rng = np.random.default_rng(seed)
    occ = rng.random((48, 48)) < 0.10
    occ[38:47, 38:47] = False
    goal = np.array([42, 42])
    assert ObstaclePotentialConfig().gamma == 2.0
    assert _field_path_excess(occ, goal, ObstaclePotentialConfig()) < 1.035
    assert _field_path_excess(occ, goal, ObstaclePotentialConfig(gamma=5.0)) > 1.035
