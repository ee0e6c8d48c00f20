"""The paper's artificial potentials (Section IV-B), with its parameter conditions.

- Interaction (Morse): rho'_I(d) = -a exp(-d / k_a) + b exp(-d / k_r), rho_I = rho'_I + zeta,
  with a, b, k_a, k_r > 0, b >= a, k_a > k_r and b k_r / (a k_a) < 1. Its minimum is at
  d_min = ln(b k_a / (a k_r)) k_a k_r / (k_a - k_r) (the paper prints the log's argument
  upside down); zeta > |rho'_I(d_min)| makes rho_I positive.
- Goal: rho_G(p) = a_G exp(d(p) / k_G), with d the distance to the goal: the paper's
  straight-line |p - p_g| (``goal_potential.distance = "euclidean"``) or the distance
  over free paths (``"geodesic"``, the default; :mod:`mrfswarm.discrete.goal_distance`), which
  leaves the static field no local minimum but the goal.
- Obstacle: m_hat = Gamma where P(occupied) >= 0.5 else 0, convolved with a Gaussian of
  sigma_hat cells.
- Static field rho_S = rho_G + rho_O: one array over the grid, computed once per scenario.

Grids are (W, H) or voxel grids (W, H, D): every field here is computed on the grid's own
shape (the blur is an n-D Gaussian, distances count all axes), by the same lines.

Units. The potentials' length parameters are in CELLS: the Morse lengths k_a and k_r
(``interaction.k_a``, ``interaction.k_r``), the goal length k_G (``goal_potential.k``) and
the blur sigma_hat (``obstacle_potential.sigma``). The paper's table gives them for its
1 m cells; read in cells, they keep the swarm's shape and the fields' slopes, measured in
cells, the same on any grid: a map drawn with 0.25 m cells has d_min = 8.42 cells = 2.1 m,
not 8.42 m (more than a 6 x 4 m arena, where the swarm could never form). So the discrete
plan of a map, in cells, does not depend on its resolution (bit for bit when the
resolution is a power of two). The functions below measure distances in metres (cell
distances times the resolution) and take the lengths in metres too: :meth:`Morse.from_config`
and :func:`goal_field` convert the config's cells with the grid's resolution, in one place each.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from mrfswarm.config import GoalPotentialConfig, InteractionConfig, ObstaclePotentialConfig
from mrfswarm.discrete.goal_distance import GoalDistance, goal_distance
from mrfswarm.errors import ConfigError, ScenarioError
from mrfswarm.geometry import norm

#: zeta = ZETA_MARGIN * |rho'_I(d_min)| when the config leaves zeta unset.
ZETA_MARGIN = 1.01


def morse_violation(a: float, b: float, k_a: float, k_r: float) -> tuple[str, str] | None:
    """The first of the paper's conditions on the Morse parameters that fails, or None.

    The conditions: a, b, k_a, k_r > 0 (finite), b >= a, k_a > k_r and
    b k_r / (a k_a) < 1. Returns ``(short, message)``: a short name of the condition (for
    tables and figures) and a message naming the config keys (for :class:`ConfigError`).
    """
    for name, v in (("a", a), ("b", b), ("k_a", k_a), ("k_r", k_r)):
        if not (math.isfinite(v) and v > 0):
            return f"{name} <= 0", f"interaction.{name} = {v!r}: must be > 0"
    if b < a:
        return "b_I < a_I", f"interaction.b = {b!r}: must be >= interaction.a = {a!r}"
    if k_a <= k_r:
        return "k_a <= k_r", f"interaction.k_a = {k_a!r}: must be > interaction.k_r = {k_r!r}"
    ratio = b * k_r / (a * k_a)
    if ratio >= 1:
        return (f"b k_r / (a k_a) = {ratio:.2f} >= 1",
                f"interaction: b * k_r / (a * k_a) = {ratio:.4g} must be < 1 (a={a}, b={b}, k_a={k_a}, k_r={k_r})")
    return None


@dataclass(frozen=True)
class Morse:
    """The Morse interaction potential rho_I(d) = -a e^{-d/k_a} + b e^{-d/k_r} + zeta.

    Raises
    ------
    ConfigError
        If the parameters break the paper's conditions (naming the parameter), or zeta
        does not make the potential positive.
    """

    a: float = 0.7
    b: float = 0.9
    k_a: float = 14.0
    k_r: float = 4.0
    zeta: float | None = None

    def __post_init__(self) -> None:
        broken = morse_violation(self.a, self.b, self.k_a, self.k_r)
        if broken is not None:
            raise ConfigError(broken[1])
        depth = abs(float(self.raw(self.d_min)))
        if self.zeta is None:
            object.__setattr__(self, "zeta", ZETA_MARGIN * depth)
        elif not self.zeta > depth:
            raise ConfigError(f"interaction.zeta = {self.zeta!r}: must be > |rho'_I(d_min)| = {depth:.6g}")

    @classmethod
    def from_config(cls, c: InteractionConfig, resolution: float = 1.0) -> Morse:
        """The potential of the config, in metres: ``k_a`` and ``k_r`` are given in cells of ``resolution`` m.

        The paper's conditions and zeta do not depend on the scale (d_min scales with it,
        rho'_I(d_min) does not), so the config is valid at every resolution or at none.
        """
        return cls(a=c.a, b=c.b, k_a=c.k_a * resolution, k_r=c.k_r * resolution, zeta=c.zeta)

    @property
    def d_min(self) -> float:
        """Distance of the minimum: ln(b k_a / (a k_r)) k_a k_r / (k_a - k_r)."""
        return math.log(self.b * self.k_a / (self.a * self.k_r)) * self.k_a * self.k_r / (self.k_a - self.k_r)

    def raw(self, d: np.ndarray | float) -> np.ndarray | float:
        """rho'_I(d), without zeta."""
        d = np.abs(d)
        return -self.a * np.exp(-d / self.k_a) + self.b * np.exp(-d / self.k_r)

    def __call__(self, d: np.ndarray | float) -> np.ndarray | float:
        """rho_I(d) = rho'_I(d) + zeta (positive)."""
        zeta = self.zeta
        assert zeta is not None  # set by __post_init__
        return self.raw(d) + zeta


#: exp(x) overflows float64 above ~709.8; a goal distance beyond this many k_G is refused.
MAX_EXPONENT = 700.0


def straight_distance(shape: tuple[int, ...], goal_cell: np.ndarray, resolution: float) -> np.ndarray:
    """|p - p_g| (metres) from every cell of a grid of ``shape`` to ``goal_cell``."""
    axes = np.meshgrid(*(np.arange(n) for n in shape), indexing="ij")
    return norm(np.stack([x - g for x, g in zip(axes, goal_cell)], axis=-1)) * resolution


def goal_field(shape: tuple[int, ...], goal_cell: np.ndarray | None, resolution: float,
               cfg: GoalPotentialConfig, distance: np.ndarray | None = None) -> np.ndarray:
    """rho_G over every cell, of the grid's ``shape`` ((W, H) or (W, H, D)); zeros when there is no goal.

    rho_G(p) = a_G exp(d(p) / k_G), d in metres: ``distance`` (of ``shape``) if given (``inf``
    gives ``inf``), else the straight-line distance |p - p_g|; k_G = ``cfg.k`` cells of
    ``resolution`` metres.

    Raises
    ------
    ScenarioError
        The goal is so far that exp(d / k_G) would overflow (names goal_potential.k).
    """
    if goal_cell is None:
        return np.zeros(shape)
    if distance is None:
        distance = straight_distance(shape, goal_cell, resolution)
    finite = distance[np.isfinite(distance)]
    far = float(finite.max(initial=0.0)) / resolution  # cells
    if far / cfg.k > MAX_EXPONENT:
        raise ScenarioError(
            f"goal_potential.k = {cfg.k:g} cells is too small for this map: cells lie {far:.0f} cells from the goal "
            f"(goal_potential.distance = {cfg.distance!r}) and exp(d / k) overflows; use k >= {far / MAX_EXPONENT:.3g}")
    return cfg.a * np.exp(distance / (cfg.k * resolution))


def obstacle_field(prob: np.ndarray, cfg: ObstaclePotentialConfig) -> np.ndarray:
    """rho_O = (Gamma * [P(occupied) >= 0.5]) convolved with a Gaussian of sigma cells, on ``prob``'s shape (any d)."""
    m_hat = np.where(prob >= 0.5, cfg.gamma, 0.0)
    if cfg.sigma == 0:
        return m_hat
    return ndimage.gaussian_filter(m_hat, sigma=cfg.sigma, mode="nearest")


def goal_distances(prob: np.ndarray, goal_cell: np.ndarray, resolution: float, goal_cfg: GoalPotentialConfig,
                   obstacle_cfg: ObstaclePotentialConfig, order: int = 2) -> GoalDistance:
    """The free-path distances to the goal, and the distance rho_G uses (``goal_cfg.distance``).

    ``"geodesic"``: the free-path distance with the obstacle potential climbed counted at
    k_G / a_G metres per unit (k_G in metres: ``goal_cfg.k`` cells of ``resolution`` m) (:func:`mrfswarm.discrete.goal_distance.goal_distance`), which
    leaves rho_S no local minimum but the goal; ``"euclidean"``: the straight-line
    distance of the paper (``path`` is still the free-path length, for reporting).
    """
    free = prob < 0.5
    if goal_cfg.distance == "geodesic":
        return goal_distance(free, goal_cell, resolution, order, obstacle_field(prob, obstacle_cfg),
                             climb_weight=goal_cfg.k * resolution / goal_cfg.a)
    d = goal_distance(free, goal_cell, resolution, order)
    return GoalDistance(path=d.path, field=straight_distance(prob.shape, goal_cell, resolution), next_cell=d.next_cell)


def static_field(prob: np.ndarray, goal_cell: np.ndarray | None, resolution: float,
                 goal_cfg: GoalPotentialConfig, obstacle_cfg: ObstaclePotentialConfig, order: int = 2,
                 distances: GoalDistance | None = None) -> np.ndarray:
    """rho_S = rho_G + rho_O over the grid, shape (W, H) or (W, H, D), computed once per scenario.

    The goal term uses ``goal_cfg.distance`` (``distances`` if already computed by
    :func:`goal_distances`; ``order`` is the label-set order n, which sets the search
    graph). With ``"geodesic"``, occupied cells and free cells without a path to the goal
    are ``inf``.
    """
    if goal_cell is not None and distances is None:
        distances = goal_distances(prob, goal_cell, resolution, goal_cfg, obstacle_cfg, order)
    d = None if distances is None else distances.field
    return goal_field(prob.shape, goal_cell, resolution, goal_cfg, d) + obstacle_field(prob, obstacle_cfg)
