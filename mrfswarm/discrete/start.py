"""Start swarms: explicit positions, or sampled as the paper does.

The paper samples the initial positions "from a multivariate Gaussian distribution with
mean set to a fixed starting position for the robot team", each robot on a distinct free
cell, with every robot having a neighbour (N_i != ∅, which the k-NN graph guarantees for
1 <= k < N). Robots sit on cell centres in the discrete stage.
"""

from __future__ import annotations

import logging

import numpy as np

from mrfswarm.errors import ConfigError, ScenarioError
from mrfswarm.maps import OccupancyGrid

log = logging.getLogger(__name__)

_EXPLICIT_KEYS = {"positions"}
_SAMPLED_KEYS = {"center", "n_robots", "sigma", "seed"}
_MAX_DRAWS_PER_ROBOT = 2000
#: ``scenario.start.sigma`` when unset, in cells (2 m at the paper's 1 m cells): the swarm's
#: spread, like its shape under the potentials, counts cells.
DEFAULT_SIGMA_CELLS = 2.0


def _fmt(p) -> str:
    return "(" + ", ".join(f"{float(v):g}" for v in p) + ")"


def place(grid: OccupancyGrid, points: np.ndarray, what: str = "robot") -> np.ndarray:
    """Cells of world ``points`` (N, 2), checked: on the map, free, one robot per cell.

    Raises
    ------
    ScenarioError
        Naming the robot, its position and the cell.
    """
    pts = np.asarray(points, dtype=float)
    cells = grid.world_to_cell(pts)
    seen: dict[tuple[int, int], int] = {}
    for i, (p, c) in enumerate(zip(pts, cells)):
        if not grid.in_bounds(c):
            x0, x1, y0, y1 = grid.extent
            raise ScenarioError(f"{what} {i} at {_fmt(p)} is off the map (x in [{x0:g}, {x1:g}), y in [{y0:g}, {y1:g}))")
        if not grid.is_free(c):
            raise ScenarioError(f"{what} {i} at {_fmt(p)} is inside an obstacle (cell {_fmt(c)})")
        key = (int(c[0]), int(c[1]))
        if key in seen:
            raise ScenarioError(f"robots {seen[key]} and {i} are both in cell {_fmt(c)} (at {_fmt(pts[seen[key]])} and {_fmt(p)})")
        seen[key] = i
    return cells.astype(np.intp)


def _number(spec: dict, key: str, positive: bool = False) -> float:
    v = spec[key]
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v):
        raise ConfigError(f"scenario.start.{key} = {v!r}: must be a number")
    if positive and v <= 0:
        raise ConfigError(f"scenario.start.{key} = {v!r}: must be > 0")
    return float(v)


def start_cells(spec: dict, grid: OccupancyGrid, seed: int | None = None) -> np.ndarray:
    """The start cells (N, 2) from the config table ``scenario.start``.

    ``{positions = [[x, y], ...]}`` places robots explicitly (metres, snapped to the cell
    they fall in); ``{center = [x, y], n_robots = N, sigma = S, seed = K}`` samples them from
    N(center, S^2 I) (metres; S unset: :data:`DEFAULT_SIGMA_CELLS` cells), snapped to distinct free cells, redrawing what falls off the map, in
    an obstacle or on a taken cell. ``seed`` overrides the table's seed (``--seed``).
    """
    keys = set(spec)
    if "positions" in keys:
        extra = keys - _EXPLICIT_KEYS
        if extra:
            raise ConfigError(f"unknown config key scenario.start.{sorted(extra)[0]} next to positions; "
                              "give either positions or center/n_robots/sigma/seed")
        pos = spec["positions"]
        try:
            arr = np.array(pos, dtype=float)
        except (TypeError, ValueError):
            raise ConfigError(f"scenario.start.positions must be a list of [x, y] pairs, got {pos!r}") from None
        if arr.ndim != 2 or arr.shape[1] != 2 or len(arr) == 0:
            raise ConfigError(f"scenario.start.positions must be a list of [x, y] pairs, got {pos!r}")
        if not np.all(np.isfinite(arr)):
            raise ConfigError(f"scenario.start.positions must be finite, got {pos!r}")
        return place(grid, arr)
    unknown = keys - _SAMPLED_KEYS
    if unknown:
        raise ConfigError(f"unknown config key scenario.start.{sorted(unknown)[0]}; allowed: positions, or "
                          f"{', '.join(sorted(_SAMPLED_KEYS))}")
    missing = {"center", "n_robots"} - keys
    if missing:
        raise ConfigError(f"scenario.start needs positions, or center and n_robots (missing {', '.join(sorted(missing))})")
    center = spec["center"]
    if (not isinstance(center, (list, tuple)) or len(center) != 2
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in center)):
        raise ConfigError(f"scenario.start.center must be [x, y], got {center!r}")
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
        raise ScenarioError(f"scenario.start.center {_fmt(c)} is off the map")
    if n > int(grid.free.sum()):
        raise ScenarioError(f"scenario.start.n_robots = {n}: the map has only {int(grid.free.sum())} free cells")
    rng = np.random.default_rng(seed)
    taken: set[tuple[int, int]] = set()
    cells: list[np.ndarray] = []
    draws = 0
    while len(cells) < n:
        if draws > _MAX_DRAWS_PER_ROBOT * n:
            raise ScenarioError(
                f"could not place {n} robots on distinct free cells around {_fmt(c)} with sigma {sigma:g} "
                f"(placed {len(cells)}); increase scenario.start.sigma or move the centre")
        batch = grid.world_to_cell(rng.normal(c, sigma, size=(n, 2)))
        draws += n
        for cell in batch:
            key = (int(cell[0]), int(cell[1]))
            if key in taken or not grid.in_bounds(cell) or not grid.is_free(cell):
                continue
            taken.add(key)
            cells.append(cell)
            if len(cells) == n:
                break
    return np.array(cells, dtype=np.intp)
