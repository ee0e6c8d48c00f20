"""A scenario: the map, the start swarm, the goal and the fields, built from a config."""

from __future__ import annotations

import dataclasses
import logging
import math
import numbers
import os
from dataclasses import dataclass

import numpy as np

from mrfswarm.config import Config, validated
from mrfswarm.continuous.receding_horizon import flight_model
from mrfswarm.discrete.congestion import CongestionField
from mrfswarm.discrete.goal_distance import GoalDistance, GoalGraph
from mrfswarm.discrete.interaction_graph import check_k
from mrfswarm.discrete.planner import DiscreteProblem
from mrfswarm.discrete.potentials import Morse, goal_distances, obstacle_field, static_field
from mrfswarm.discrete.robot_outcomes import goal_region_radius
from mrfswarm.discrete.start import format_point, map_box, say_snapped, start_cells
from mrfswarm.discrete.step_mrf import check_order
from mrfswarm.errors import ConfigError, ScenarioError
from mrfswarm.maps import OccupancyGrid, load_map
from mrfswarm.maps.spec import AXES

log = logging.getLogger(__name__)

#: ``scenario.goal_radius`` when the config leaves it unset, in cells: 3 m at the paper's 1 m cells.
DEFAULT_GOAL_RADIUS_CELLS = 3.0


def goal_radius_m(cfg: Config, resolution: float) -> float:
    """``scenario.goal_radius`` (metres), or :data:`DEFAULT_GOAL_RADIUS_CELLS` cells of ``resolution`` m when unset.

    A swarm's size at its goal is set by the potentials, which are in cells
    (:mod:`mrfswarm.discrete.potentials`), so the default radius is too: 3 m would be
    most of a 6 x 4 m arena drawn in 0.25 m cells.
    """
    r = cfg.scenario.goal_radius
    return DEFAULT_GOAL_RADIUS_CELLS * resolution if r is None else r


@dataclass(frozen=True)
class Scenario:
    """Everything fixed before planning.

    Attributes
    ----------
    grid
        The occupancy grid.
    start
        (N, d) start cells, d = ``grid.ndim`` (2, or 3 on a voxel map).
    goal
        Goal cell (d,), or None for the free-space formation experiments.
    static
        rho_S over the grid, ``grid.shape``.
    morse
        The interaction potential, in metres (the config's lengths are in cells).
    config
        The config it was built from.
    goal_radius
        ``scenario.goal_radius`` in metres (:func:`goal_radius_m`: 3 cells when unset).
    distances
        Distances from every cell to the goal over free paths (None without a goal).
    goal_region_radius
        Robots within this free-path distance (metres) of the goal are at the goal
        (:func:`mrfswarm.discrete.robot_outcomes.goal_region_radius`); None without a goal.
    """

    grid: OccupancyGrid
    start: np.ndarray
    goal: np.ndarray | None
    static: np.ndarray
    morse: Morse
    config: Config
    goal_radius: float
    distances: GoalDistance | None = None
    goal_region_radius: float | None = None

    @property
    def n_robots(self) -> int:
        return len(self.start)

    @property
    def goal_world(self) -> np.ndarray | None:
        return None if self.goal is None else self.grid.cell_to_world(self.goal)

    @property
    def downwash(self) -> float:
        """``scenario.downwash`` (c >= 1): dz counts 1/c in the separation metric of a voxel map."""
        return self.config.scenario.downwash

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
            trim_escape=c.mrf.trim_escape,
            trim_slack=c.mrf.trim_slack,
            contested=c.mrf.contested,
            follow=c.mrf.follow,
            goal_distance=self.distances.field if self.distances is not None and c.goal_potential.distance == "geodesic"
            else None,
            goal_path=None if self.distances is None else self.distances.path,
            goal_region_radius=0.0 if self.goal_region_radius is None else self.goal_region_radius,
            downwash=c.scenario.downwash,
            congestion=self.congestion_field(),
            merge_waits=c.mrf.merge_waits,
            drop_loops=c.mrf.drop_loops,
            straighten=c.mrf.straighten,
            escalation=None if c.mrf.escalation == "none" else c.mrf.escalation,
            # with the continuous stage off too: a discrete-only run (scoping a big swarm, a sweep) plans what the
            # full run flies (without the model its merges and the "auto" rule were judged by cells instead)
            flight=flight_model(c.smoothing, self.grid.resolution, c.scenario.robot_radius),
            pick=flight_model(c.smoothing, self.grid.resolution, c.scenario.robot_radius, "fast"),
        )

    def congestion_field(self) -> CongestionField | None:
        """The goal field's congestion pricing (None with ``goal_potential.congestion`` 0 or without a goal)."""
        g = self.config.goal_potential
        if g.congestion_weight <= 0 or self.goal is None or self.distances is None:
            return None
        obstacle = obstacle_field(self.grid.prob, self.config.obstacle_potential)
        graph = self.distances.graph  # the geodesic field's own (congestion needs it), built with the same arguments
        if graph is None:
            graph = GoalGraph.build(self.grid.free, self.goal, self.grid.resolution, self.config.mrf.order, obstacle,
                                    climb_weight=g.k * self.grid.resolution / g.a)
        return CongestionField(graph=graph, obstacle=obstacle, goal_cfg=g, resolution=self.grid.resolution,
                               weight=g.congestion_weight, every=g.congestion_every, goal_path=self.distances.path,
                               region_radius=0.0 if self.goal_region_radius is None else self.goal_region_radius)


#: Bytes a cell (2-D) or a voxel (3-D) takes at the peak of a scenario's build, its goal field's search graph
#: (measured by a map tour: a 2000 x 2000 MovingAI map 2.4 GB, about 600 bytes a cell; 128^3 voxels 3.9 GB, about
#: 1.8 kB a voxel). The map's cell limit (10^8) allows maps that need some 60 GB.
BUILD_BYTES_PER_CELL = {2: 600, 3: 1800}


def machine_memory() -> int | None:
    """Bytes of physical memory, or None where the system does not say."""
    try:
        return int(os.sysconf("SC_PHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (AttributeError, ValueError, OSError):
        return None


def check_memory(grid: OccupancyGrid) -> None:
    """Refuse, in one line, a map whose build would need more than the machine's memory
    (:data:`BUILD_BYTES_PER_CELL`): such a run was killed by the system without a word (a map tour)."""
    need, have = grid.prob.size * BUILD_BYTES_PER_CELL[grid.ndim], machine_memory()
    if have is not None and need > have:
        k = math.ceil((need / have) ** (1 / grid.ndim))
        raise ScenarioError(f"scenario.map: {' x '.join(map(str, grid.shape))} cells need about {need / 1e9:.2g} GB "
                            f"to plan on (about {BUILD_BYTES_PER_CELL[grid.ndim]} bytes a cell), more than this "
                            f"machine's {have / 1e9:.2g} GB: draw it in coarser cells (scenario.map.coarsen = {k} or "
                            "more) or crop it")


def build_scenario(cfg: Config, seed: int | None = None) -> Scenario:
    """Load the map, place the swarm and the goal, and compute rho_S once.

    ``cfg`` is checked as :func:`mrfswarm.plan` checks it (:func:`mrfswarm.config.validated`): a config changed in
    code may hold what a file may not. ``seed`` (an integer >= 0) overrides the sampled start's seed.

    Raises
    ------
    ConfigError, ScenarioError
        Bad parameters (``cfg`` not a :class:`Config`, ``seed`` not an integer >= 0), a robot or the goal off the
        map or in an obstacle, two robots in one cell, k out of range, a search order too large for the map's
        dimension.
    """
    # called alone (stage by stage), a dict ended in "'dict' object has no attribute 'scenario'", a negative
    # robot_radius set in code planned, a string seed in NumPy's "SeedSequence expects int" (a library tour)
    cfg = validated(cfg)
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, numbers.Integral) or seed < 0):
        raise ConfigError(f"seed = {seed!r}: must be an integer >= 0")
    grid = load_map(cfg.scenario.map, cfg.base_dir)
    check_memory(grid)
    check_order(cfg.mrf.order, grid.ndim, cfg.scenario.downwash)
    morse = Morse.from_config(cfg.interaction, grid.resolution)  # k_a, k_r in cells (potentials module)
    if cfg.smoothing.enabled and not cfg.scenario.robot_radius < 0.5 * grid.resolution:
        # the discrete stage keeps robots one cell apart and half a cell off walls: a robot as
        # wide as a cell leaves the continuous stage no room
        k = int(2 * cfg.scenario.robot_radius // grid.resolution) + 1  # the cells of a coarse cell that fits it
        raise ConfigError(f"scenario.robot_radius = {cfg.scenario.robot_radius:g} m must be below half a cell "
                          f"({0.5 * grid.resolution:g} m on this map; scenario.map.coarsen = {k} draws it in "
                          f"{k * grid.resolution:g} m cells)")
    start = start_cells(cfg.scenario.start, grid, seed, downwash=cfg.scenario.downwash)
    check_k(cfg.interaction.k, len(start))
    goal = None if cfg.scenario.goal is None else goal_cell(cfg.scenario.goal, grid)
    distances = None
    if goal is not None:
        distances = goal_distances(grid.prob, goal, grid.resolution, cfg.goal_potential, cfg.obstacle_potential,
                                   cfg.mrf.order)
        if cfg.goal_potential.congestion_weight <= 0:  # only the congestion searches the graph again: not kept
            distances = dataclasses.replace(distances, graph=None)
        if cfg.goal_potential.distance == "geodesic":
            _check_reachable(grid, start, goal, distances)
    static = static_field(grid.prob, goal, grid.resolution, cfg.goal_potential, cfg.obstacle_potential,
                          cfg.mrf.order, distances)
    goal_radius = goal_radius_m(cfg, grid.resolution)
    region = None if distances is None else goal_region_radius(distances.path, len(start), goal_radius)
    if region is not None and distances is not None and cfg.mrf.arrival:
        _say_starts_in_goal_region(distances.path[tuple(np.asarray(start).T)], region)
    return Scenario(grid=grid, start=start, goal=goal, static=static, morse=morse, config=cfg, goal_radius=goal_radius,
                    distances=distances, goal_region_radius=region)


#: Share of the robots starting inside the goal region above which a run says so (every bench map and config: 0).
STARTS_IN_GOAL_REGION = 0.1


def _say_starts_in_goal_region(start_distance: np.ndarray, region: float) -> None:
    """Warn when many robots start inside the goal region: the plan ends ("arrived") once every robot is in it, so a
    swarm too big for its map (the region holds 4 free cells per robot) "arrived" with its centre 43 m from the goal
    and no robot nearer than 25 m (a scale tour: 1000 robots on swarm100's 100 x 60 m field)."""
    inside = int(np.count_nonzero(start_distance <= region))
    if inside > STARTS_IN_GOAL_REGION * len(start_distance):
        log.warning("%d of %d robots start inside the goal region (%.3g m of free path around the goal: "
                    "scenario.goal_radius plus room for 4 free cells per robot), where the plan counts them arrived: "
                    "give the swarm a bigger map or fewer robots, or set mrf.arrival = false to plan on to convergence",
                    inside, len(start_distance), region)


def goal_cell(goal: tuple[float, ...], grid: OccupancyGrid) -> np.ndarray:
    """The cell (d,) of ``scenario.goal`` (metres): on the map, free, one coordinate per axis of the map.

    Raises
    ------
    ConfigError
        The wrong number of coordinates (as for a start position: the value's shape).
    ScenarioError
        Naming the goal: off the map, in an obstacle.
    """
    g = np.asarray(goal, dtype=float)
    if g.shape != (grid.ndim,):
        raise ConfigError(f"scenario.goal = {[float(v) for v in g]!r}: {g.size} coordinates on a {grid.ndim}-D map, "
                          f"give {AXES[grid.ndim]}")
    gc = grid.world_to_cell(g)
    if not grid.in_bounds(gc):
        raise ScenarioError(f"scenario.goal {format_point(g)} is off the map ({map_box(grid)})")
    if not grid.is_free(gc):
        raise ScenarioError(f"scenario.goal {format_point(g)} is inside {grid.occupied_as(gc)} (cell {format_point(gc)})")
    say_snapped(grid, g, gc, "scenario.goal", "goal")
    return gc.astype(np.intp)


def _check_reachable(grid: OccupancyGrid, start: np.ndarray, goal: np.ndarray, distances: GoalDistance) -> None:
    """Every robot needs a free path to the goal for the geodesic field to guide it.

    Raises
    ------
    ScenarioError
        Naming the robots without a path (or saying that none has one).
    """
    cut = ~distances.reachable[tuple(start.T)]
    if not cut.any():
        return
    g = grid.cell_to_world(goal)
    region = int(distances.reachable.sum())
    if cut.all():
        raise ScenarioError(
            f"scenario.goal {format_point(g)} cannot be reached: no robot has a free path to it (the goal's "
            f"free region has {region} cells)")
    bad = np.flatnonzero(cut)
    where = ", ".join(f"robot {i} at {format_point(grid.cell_to_world(start[i]))}" for i in bad[:3])
    more = f" and {len(bad) - 3} more" if len(bad) > 3 else ""
    raise ScenarioError(f"no free path to the goal {format_point(g)} from {where}{more}; move "
                        f"{'it' if len(bad) == 1 else 'them'} into the "
                        f"goal's free region or set goal_potential.distance = \"euclidean\"")
