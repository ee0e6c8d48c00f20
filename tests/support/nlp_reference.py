"""NLPs with known optima for every NLP backend (``tests/solvers/nlp/``).

Each reference is analytic or constructed from a chosen KKT point; no backend makes one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from solvers.nlp import NLPProblem


@dataclass(frozen=True)
class NLPReference:
    name: str
    problem: NLPProblem
    x: np.ndarray
    objective: float

    @property
    def has_linear_rows(self) -> bool:
        return self.problem.has_linear_rows


def _rosenbrock(x: np.ndarray) -> float:
    return float((1 - x[0]) ** 2 + 100 * (x[1] - x[0] ** 2) ** 2)


def _rosenbrock_grad(x: np.ndarray) -> np.ndarray:
    return np.array([-2 * (1 - x[0]) - 400 * x[0] * (x[1] - x[0] ** 2), 200 * (x[1] - x[0] ** 2)])


def rosenbrock() -> NLPReference:
    """Unconstrained Rosenbrock from the classic start (-1.2, 1): minimum 0 at (1, 1)."""
    return NLPReference("rosenbrock", NLPProblem(_rosenbrock, _rosenbrock_grad, [-1.2, 1.0]), np.ones(2), 0.0)


def bounded_rosenbrock() -> NLPReference:
    """Rosenbrock with x <= 1/2: on the valley y = x^2 the cost is (1 - x)^2, least at the
    bound x = 1/2, so the minimum is 1/4 at (1/2, 1/4) with the bound active."""
    problem = NLPProblem(_rosenbrock, _rosenbrock_grad, [-1.2, 1.0], [-2.0, -2.0], [0.5, 2.0])
    return NLPReference("bounded_rosenbrock", problem, np.array([0.5, 0.25]), 0.25)


def _quadratic(Q: np.ndarray, c: np.ndarray, x0, lower, upper, A=None, lb=-np.inf, ub=np.inf) -> NLPProblem:
    return NLPProblem(lambda x: float(0.5 * x @ Q @ x + c @ x), lambda x: Q @ x + c, x0, lower, upper, A, lb, ub)


def bounded_quadratic(seed: int = 0) -> NLPReference:
    """A strictly convex quadratic on a box, built from its KKT point: x*_0 at its lower bound
    (gradient > 0 there), x*_1 at its upper bound (gradient < 0), the rest interior (gradient 0)."""
    rng = np.random.default_rng(seed)
    n = 6
    M = rng.normal(size=(n, n))
    Q = M @ M.T + n * np.eye(n)
    lower, upper = -np.ones(n), np.ones(n)
    x = rng.uniform(-0.5, 0.5, n)
    x[0], x[1] = lower[0], upper[1]
    g = np.zeros(n)
    g[0], g[1] = 2.0, -3.0  # multipliers of the active bounds, with the signs of a minimum
    c = g - Q @ x
    return NLPReference("bounded_quadratic", _quadratic(Q, c, np.zeros(n), lower, upper), x,
                        float(0.5 * x @ Q @ x + c @ x))


def linear_rows_quadratic(seed: int = 1) -> NLPReference:
    """A strictly convex quadratic with an equality row (sum x = 1) and an active inequality
    row (x_0 - x_1 <= -0.2), built from its KKT point: Q x* + c + A' y = 0."""
    rng = np.random.default_rng(seed)
    n = 4
    M = rng.normal(size=(n, n))
    Q = M @ M.T + n * np.eye(n)
    A = np.array([[1.0, 1.0, 1.0, 1.0], [1.0, -1.0, 0.0, 0.0]])
    lb, ub = np.array([1.0, -np.inf]), np.array([1.0, -0.2])
    x = np.array([0.1, 0.3, 0.25, 0.35])  # sum 1, x0 - x1 = -0.2
    y = np.array([0.7, 1.5])  # any sign on the equality; > 0 at the active upper side
    c = -Q @ x - A.T @ y
    problem = _quadratic(Q, c, np.full(n, 0.25) - [0.1, 0, 0, 0], -np.inf, np.inf, A, lb, ub)
    return NLPReference("linear_rows_quadratic", problem, x, float(0.5 * x @ Q @ x + c @ x))


def all_references() -> list[NLPReference]:
    return [rosenbrock(), bounded_rosenbrock(), bounded_quadratic(), linear_rows_quadratic()]


class NaNRegion:
    """A separable quadratic sum a_i (x_i - 1)^2 + 0.2 sum x on [0, 10]^3 that is not defined
    (NaN) where some x_i < 0.8; minimum at x_i = 1 - 0.1 / a_i, inside the defined region.
    From (1.6, 1.6, 1.6) the stiff coordinates make a first quasi-Newton step overshoot into
    the undefined region. ``hits`` counts the evaluations there."""

    a = np.array([1.0, 30.0, 100.0])

    def __init__(self) -> None:
        self.hits = 0
        self.x = 1 - 0.1 / self.a
        self.objective = float(self.fun(self.x))
        self.hits = 0

    def fun(self, x: np.ndarray) -> float:
        if np.any(x < 0.8):
            self.hits += 1
            return float("nan")
        return float(np.sum(self.a * (x - 1) ** 2) + 0.2 * np.sum(x))

    def grad(self, x: np.ndarray) -> np.ndarray:
        if np.any(x < 0.8):
            return np.full(3, np.nan)
        return 2 * self.a * (x - 1) + 0.2

    def problem(self) -> NLPProblem:
        return NLPProblem(self.fun, self.grad, [1.6, 1.6, 1.6], 0.0, 10.0)
