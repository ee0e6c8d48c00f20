"""The paper's artificial potentials (Section IV-B), with its parameter conditions.

- Interaction (Morse): rho'_I(d) = -a exp(-d / k_a) + b exp(-d / k_r), rho_I = rho'_I + zeta,
  with a, b, k_a, k_r > 0, b >= a, k_a > k_r and b k_r / (a k_a) < 1. Its minimum is at
  d_min = ln(b k_a / (a k_r)) k_a k_r / (k_a - k_r) (the paper prints the log's argument
  upside down); zeta > |rho'_I(d_min)| makes rho_I positive.
- Goal: rho_G(p) = a_G exp(|p - p_g| / k_G).
- Obstacle: m_hat = Gamma where P(occupied) >= 0.5 else 0, convolved with a Gaussian of
  sigma_hat cells.
- Static field rho_S = rho_G + rho_O: one array over the grid, computed once per scenario.

Distances are in metres (cell distances times the grid resolution).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from mrfswarm.config import GoalPotentialConfig, InteractionConfig, ObstaclePotentialConfig
from mrfswarm.errors import ConfigError

#: zeta = ZETA_MARGIN * |rho'_I(d_min)| when the config leaves zeta unset.
ZETA_MARGIN = 1.01


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
        for name in ("a", "b", "k_a", "k_r"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ConfigError(f"interaction.{name} = {v!r}: must be > 0")
        if self.b < self.a:
            raise ConfigError(f"interaction.b = {self.b!r}: must be >= interaction.a = {self.a!r}")
        if self.k_a <= self.k_r:
            raise ConfigError(f"interaction.k_a = {self.k_a!r}: must be > interaction.k_r = {self.k_r!r}")
        ratio = self.b * self.k_r / (self.a * self.k_a)
        if ratio >= 1:
            raise ConfigError(
                f"interaction: b * k_r / (a * k_a) = {ratio:.4g} must be < 1 (a={self.a}, b={self.b}, "
                f"k_a={self.k_a}, k_r={self.k_r})"
            )
        depth = abs(self.raw(self.d_min))
        if self.zeta is None:
            object.__setattr__(self, "zeta", ZETA_MARGIN * depth)
        elif not self.zeta > depth:
            raise ConfigError(f"interaction.zeta = {self.zeta!r}: must be > |rho'_I(d_min)| = {depth:.6g}")

    @classmethod
    def from_config(cls, c: InteractionConfig) -> Morse:
        return cls(a=c.a, b=c.b, k_a=c.k_a, k_r=c.k_r, zeta=c.zeta)

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
        return self.raw(d) + self.zeta


def goal_field(shape: tuple[int, int], goal_cell: np.ndarray | None, resolution: float,
               cfg: GoalPotentialConfig) -> np.ndarray:
    """rho_G over every cell, shape (W, H); zeros when there is no goal.

    rho_G(p) = a_G exp(|p - p_g| / k_G), with |p - p_g| in metres.
    """
    if goal_cell is None:
        return np.zeros(shape)
    ix, iy = np.meshgrid(np.arange(shape[0]), np.arange(shape[1]), indexing="ij")
    d = np.hypot(ix - goal_cell[0], iy - goal_cell[1]) * resolution
    return cfg.a * np.exp(d / cfg.k)


def obstacle_field(prob: np.ndarray, cfg: ObstaclePotentialConfig) -> np.ndarray:
    """rho_O = (Gamma * [P(occupied) >= 0.5]) convolved with a Gaussian of sigma cells, shape (W, H)."""
    m_hat = np.where(prob >= 0.5, cfg.gamma, 0.0)
    if cfg.sigma == 0:
        return m_hat
    return ndimage.gaussian_filter(m_hat, sigma=cfg.sigma, mode="nearest")


def static_field(prob: np.ndarray, goal_cell: np.ndarray | None, resolution: float,
                 goal_cfg: GoalPotentialConfig, obstacle_cfg: ObstaclePotentialConfig) -> np.ndarray:
    """rho_S = rho_G + rho_O over the grid, shape (W, H), computed once per scenario."""
    return goal_field(prob.shape, goal_cell, resolution, goal_cfg) + obstacle_field(prob, obstacle_cfg)
