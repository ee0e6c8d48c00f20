"""Start swarms: explicit positions, or sampled as the paper does.

The paper samples the initial positions "from a multivariate Gaussian distribution with
mean set to a fixed starting position for the robot team", each robot on a distinct free
cell, with every robot having a neighbour (N_i != ∅, which the k-NN graph guarantees for
1 <= k < N). Robots sit on cell centres in the discrete stage.

On a voxel map the start is a step of the discrete plan like any other, so its robots
keep one cell apart in the downwash-scaled metric (:func:`mrfswarm.geometry.downwash_scale`,
``scenario.downwash`` = c): two robots in one column need |dz| >= c cells. Distinct
cells are one cell apart in the plane, where the rule is the paper's.
"""

from __future__ import annotations

import logging

import numpy as np
from scipy.spatial import cKDTree

from mrfswarm.errors import ConfigError, ScenarioError
from mrfswarm.geometry import downwash_scale
from mrfswarm.maps import OccupancyGrid
from mrfswarm.maps.spec import AXES

log = logging.getLogger(__name__)

_EXPLICIT_KEYS = {"positions"}
_SAMPLED_KEYS = {"center", "n_robots", "sigma", "seed"}
_MAX_DRAWS_PER_ROBOT = 2000
#: ``scenario.start.sigma`` when unset, in cells (2 m at the paper's 1 m cells): the swarm's
#: spread, like its shape under the potentials, counts cells.
DEFAULT_SIGMA_CELLS = 2.0


def format_point(p: np.ndarray | tuple[float, ...]) -> str:
    """``(x, y)`` or ``(x, y, z)`` as messages write a point or a cell."""
    return "(" + ", ".join(f"{float(v):g}" for v in p) + ")"


#: Scaled distances below 1 cell by more than rounding are too close (dz = c is exactly 1).
_TOO_CLOSE = 1.0 - 1e-9


def map_box(grid: OccupancyGrid) -> str:
    """The map's box, as an off-map message states it: ``x in [x0, x1), y in [y0, y1)[, z in [z0, z1)]``."""
    lo, hi = grid.bounds
    return ", ".join(f"{a} in [{lo[k]:g}, {hi[k]:g})" for k, a in enumerate("xyz"[:grid.ndim]))


def _crowded(cells: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """Bool (N,): whether each cell is less than one cell (scaled by ``scale``) from an EARLIER one.

    With factors 1 (the plane, or c = 1) that is a cell someone took before.
    """
    crowded = np.zeros(len(cells), dtype=bool)
    if len(cells) > 1:
        pairs = cKDTree(cells * scale).query_pairs(_TOO_CLOSE, output_type="ndarray")
        crowded[pairs.max(axis=1)] = True
    return crowded


def place(grid: OccupancyGrid, points: np.ndarray, key: str = "scenario.start.positions",
          downwash: float = 1.0) -> np.ndarray:
    """Cells of world ``points`` (N, d), checked: on the map, free, one cell apart (downwash-scaled).

    Raises
    ------
    ScenarioError
        Naming the config ``key`` the points came from and the first robot that is off the
        map, in an obstacle, in another's cell or (on a voxel map) fewer than ``downwash``
        cells above or below another, its position and the cell.
    """
    pts = np.asarray(points, dtype=float)
    cells = grid.world_to_cell(pts)
    inside = grid.in_bounds(cells)
    free = grid.is_free(cells)
    scale = downwash_scale(grid.ndim, downwash)
    crowded = np.zeros(len(cells), dtype=bool)
    crowded[free] = _crowded(cells[free], scale)  # robots before the first bad one are all free
    bad = np.flatnonzero(~free | crowded)
    if len(bad):
        i = int(bad[0])
        p, c = pts[i], cells[i]
        if not inside[i]:
            raise ScenarioError(f"{key}[{i}]: robot {i} at {format_point(p)} is off the map ({map_box(grid)})")
        if not free[i]:
            raise ScenarioError(f"{key}[{i}]: robot {i} at {format_point(p)} is inside {grid.occupied_as(c)} "
                                f"(cell {format_point(c)})")
        near = np.linalg.norm((cells[:i] - c) * scale, axis=-1) < _TOO_CLOSE
        j = int(np.flatnonzero(near)[0])
        if np.array_equal(cells[j], c):
            raise ScenarioError(f"{key}: robots {j} and {i} are both in cell {format_point(c)} "
                                f"(at {format_point(pts[j])} and {format_point(p)})")
        raise ScenarioError(f"{key}: robots {j} and {i} are in cells {format_point(cells[j])} and {format_point(c)}, "
                            f"{abs(int(c[2] - cells[j][2]))} apart in z: scenario.downwash = {downwash:g} needs "
                            f"{int(np.ceil(downwash - 1e-9))} (at {format_point(pts[j])} and {format_point(p)})")
    return cells.astype(np.intp)


def say_snapped(grid: OccupancyGrid, points: np.ndarray, cells: np.ndarray, key: str, what: str) -> None:
    """Warn (one line) when the world ``points`` given under ``key`` are not their ``cells``' centres: the plan
    starts (or ends) there, up to half a cell away from what was asked."""
    pts = np.atleast_2d(np.asarray(points, dtype=float))
    centres = grid.cell_to_world(np.atleast_2d(cells))
    moved = np.linalg.norm(centres - pts, axis=-1)
    if moved.max(initial=0.0) <= 1e-6 * grid.resolution:
        return
    i = int(np.argmax(moved))
    at = f"{format_point(pts[i])} -> {format_point(centres[i])}"
    if len(pts) == 1:
        log.warning("%s: placed at its cell's centre, %.3g m away: %s", key, moved[i], at)
    else:
        log.warning("%s: placed at cell centres, %d of %d moved, the most %s %d by %.3g m: %s", key,
                    int(np.count_nonzero(moved > 1e-6 * grid.resolution)), len(pts), what, i, moved[i], at)


def _points(value: object, key: str, d: int) -> np.ndarray:
    """World points (N, d) from a config list of N lists of d numbers (N >= 1); ``key`` names it.

    Raises
    ------
    ConfigError
        Not a non-empty list of lists of ``d`` finite numbers (on a map of ``d`` axes).
    """
    axes = AXES[d]
    if not isinstance(value, (list, tuple)) or not value:
        raise ConfigError(f"{key} must be a list of {axes} points, got {value!r}")
    for i, q in enumerate(value):
        if (not isinstance(q, (list, tuple))
                or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in q)):
            raise ConfigError(f"{key} must be a list of {axes} points, got {value!r}")
        if len(q) != d:
            raise ConfigError(f"{key}[{i}] = {list(q)!r}: {len(q)} coordinates on a {d}-D map, give {axes}")
    arr = np.array(value, dtype=float)
    if not np.all(np.isfinite(arr)):
        raise ConfigError(f"{key} must be finite, got {value!r}")
    return arr


def _number(spec: dict, key: str, positive: bool = False) -> float:
    v = spec[key]
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v):
        raise ConfigError(f"scenario.start.{key} = {v!r}: must be a number")
    if positive and v <= 0:
        raise ConfigError(f"scenario.start.{key} = {v!r}: must be > 0")
    return float(v)


def start_cells(spec: dict, grid: OccupancyGrid, seed: int | None = None, downwash: float = 1.0) -> np.ndarray:
    """The start cells (N, d) from the config table ``scenario.start``, d = ``grid.ndim``.

    ``{positions = [[x, y], ...]}`` (``[x, y, z]`` on a voxel map) places robots explicitly
    (metres, snapped to the cell they fall in); ``{center = [x, y(, z)], n_robots = N,
    sigma = S, seed = K}`` samples them from N(center, S^2 I) (metres; S unset:
    :data:`DEFAULT_SIGMA_CELLS` cells), snapped to distinct free cells, redrawing what
    falls off the map, in an obstacle or on a taken cell (draws are taken in order, in
    batches of N, so a seed gives the same swarm as it always did). ``seed`` overrides
    the table's seed (``--seed``). On a voxel map robots keep one cell apart in the
    metric scaled by ``downwash`` (``scenario.downwash``; module docstring): explicit
    positions closer are an error, sampled draws closer are redrawn.
    """
    d = grid.ndim
    axes = AXES[d]
    keys = set(spec)
    if "positions" in keys:
        extra = keys - _EXPLICIT_KEYS
        if extra:
            raise ConfigError(f"unknown config key scenario.start.{sorted(extra)[0]} next to positions; "
                              "give either positions or center/n_robots/sigma/seed")
        pts = _points(spec["positions"], "scenario.start.positions", d)
        cells = place(grid, pts, "scenario.start.positions", downwash=downwash)
        say_snapped(grid, pts, cells, "scenario.start.positions", "robot")
        return cells
    unknown = keys - _SAMPLED_KEYS
    if unknown:
        raise ConfigError(f"unknown config key scenario.start.{sorted(unknown)[0]}; allowed: positions, or "
                          f"{', '.join(sorted(_SAMPLED_KEYS))}")
    missing = {"center", "n_robots"} - keys
    if missing:
        raise ConfigError(f"scenario.start needs positions, or center and n_robots (missing {', '.join(sorted(missing))})")
    center = spec["center"]
    if (not isinstance(center, (list, tuple))
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in center)):
        raise ConfigError(f"scenario.start.center must be {axes}, got {center!r}")
    if len(center) != d:
        raise ConfigError(f"scenario.start.center = {list(center)!r}: {len(center)} coordinates on a {d}-D map, "
                          f"give {axes}")
    if not all(np.isfinite(center)):
        raise ConfigError(f"scenario.start.center must be finite, got {list(center)!r}")
    n = spec["n_robots"]
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise ConfigError(f"scenario.start.n_robots = {n!r}: must be a positive integer")
    sigma = _number(spec, "sigma", positive=True) if "sigma" in spec else DEFAULT_SIGMA_CELLS * grid.resolution
    if seed is None:
        seed = spec.get("seed", 0)
        if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
            raise ConfigError(f"scenario.start.seed = {seed!r}: must be an integer >= 0")
    c = np.asarray(center, dtype=float)
    cc = grid.world_to_cell(c)
    if not grid.in_bounds(cc):
        raise ScenarioError(f"scenario.start.center {format_point(c)} is off the map ({map_box(grid)})")
    n_free = int(grid.free.sum())
    if n > n_free:
        raise ScenarioError(f"scenario.start.n_robots = {n}: the map has only {n_free} free cell{'s' * (n_free != 1)}")
    rng = np.random.default_rng(seed)
    scale = downwash_scale(d, downwash)
    cells = np.empty((0, d), dtype=np.intp)
    draws = 0
    while len(cells) < n:
        if draws > _MAX_DRAWS_PER_ROBOT * n:
            raise ScenarioError(
                f"could not place {n} robots on distinct free cells around {format_point(c)} with sigma {sigma:g} "
                f"(placed {len(cells)}); increase scenario.start.sigma or move the centre")
        batch = grid.world_to_cell(rng.normal(c, sigma, size=(n, d)))
        draws += n
        # a draw is kept when free and one cell (scaled) from every robot placed and every earlier free draw of its
        # batch; in draw order (in the plane: the batch's first draw on a cell nobody took)
        ok = grid.is_free(batch)
        if len(cells):
            ok &= cKDTree(cells * scale).query(batch * scale, distance_upper_bound=1.0)[0] >= _TOO_CLOSE
        ok[ok] = ~_crowded(batch[ok], scale)
        cells = np.concatenate([cells, batch[ok][:n - len(cells)].astype(np.intp)])
    return cells
