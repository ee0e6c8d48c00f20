"""A scenario: the map, the start swarm, the goal and the fields, built from a config."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mrfswarm.config import Config
from mrfswarm.discrete import DiscreteProblem
from mrfswarm.errors import ConfigError, ScenarioError
from mrfswarm.interaction_graph import check_k
from mrfswarm.maps import OccupancyGrid, load_map
from mrfswarm.potentials import Morse, static_field
from mrfswarm.start import start_cells


@dataclass(frozen=True)
class Scenario:
    """Everything fixed before planning.

    Attributes
    ----------
    grid
        The occupancy grid.
    start
        (N, 2) start cells.
    goal
        Goal cell (2,), or None for the free-space formation experiments.
    static
        rho_S over the grid, (W, H).
    morse
        The interaction potential.
    config
        The config it was built from.
    """

    grid: OccupancyGrid
    start: np.ndarray
    goal: np.ndarray | None
    static: np.ndarray
    morse: Morse
    config: Config

    @property
    def n_robots(self) -> int:
        return len(self.start)

    @property
    def goal_world(self) -> np.ndarray | None:
        return None if self.goal is None else self.grid.cell_to_world(self.goal)

    def discrete_problem(self) -> DiscreteProblem:
        """The discrete stage's inputs, in cells."""
        c = self.config
        return DiscreteProblem(
            free=self.grid.free,
            static=self.static,
            start=self.start,
            goal=self.goal,
            morse=self.morse,
            resolution=self.grid.resolution,
            k=c.interaction.k,
            order=c.mrf.order,
            trim_backward=c.mrf.trim_backward,
        )


def build_scenario(cfg: Config, seed: int | None = None) -> Scenario:
    """Load the map, place the swarm and the goal, and compute rho_S once.

    Raises
    ------
    ConfigError, ScenarioError
        Bad parameters, a robot or the goal off the map or in an obstacle, two robots in
        one cell, k out of range.
    """
    morse = Morse.from_config(cfg.interaction)
    grid = load_map(cfg.scenario.map, cfg.base_dir)
    if cfg.smoothing.enabled and not cfg.scenario.robot_radius < 0.5 * grid.resolution:
        # the discrete stage keeps robots one cell apart and half a cell off walls: a robot as
        # wide as a cell leaves the continuous stage no room
        raise ConfigError(f"scenario.robot_radius = {cfg.scenario.robot_radius:g} m must be below half a cell "
                          f"({0.5 * grid.resolution:g} m on this map)")
    start = start_cells(cfg.scenario.start, grid, seed)
    check_k(cfg.interaction.k, len(start))
    goal = None
    if cfg.scenario.goal is not None:
        g = np.asarray(cfg.scenario.goal, dtype=float)
        gc = grid.world_to_cell(g)
        if not grid.in_bounds(gc):
            raise ScenarioError(f"scenario.goal ({g[0]:g}, {g[1]:g}) is off the map")
        if not grid.is_free(gc):
            raise ScenarioError(f"scenario.goal ({g[0]:g}, {g[1]:g}) is inside an obstacle (cell ({gc[0]}, {gc[1]}))")
        goal = gc.astype(np.intp)
    static = static_field(grid.prob, goal, grid.resolution, cfg.goal_potential, cfg.obstacle_potential)
    return Scenario(grid=grid, start=start, goal=goal, static=static, morse=morse, config=cfg)
