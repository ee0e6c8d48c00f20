"""The trajectory tests' references (:mod:`support.trajectories`) agree with the banded solver."""

import numpy as np

from mrfswarm.trajectory import MinSnapProblem
from mrfswarm.trajectory.banded import solve_banded
from support.trajectories import exact_banded_coefficients, kkt_trajectory, random_walk


def test_exact_reference_matches_banded_on_a_tame_problem():
    rng = np.random.default_rng(3)
    W = random_walk(rng, 3)
    p = MinSnapProblem(W, [1.0, 1.5, 0.75])
    np.testing.assert_allclose(solve_banded(p).coefficients, exact_banded_coefficients(p), atol=1e-11)


def test_kkt_reference_matches_banded():
    rng = np.random.default_rng(4)
    W = random_walk(rng, 6)
    p = MinSnapProblem(W, rng.uniform(0.5, 2.0, 6))
    ref = solve_banded(p)
    traj = kkt_trajectory(p)
    np.testing.assert_allclose(traj.tau_coefficients(), ref.coefficients, atol=1e-9)
