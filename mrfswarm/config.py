"""Experiment configuration: TOML parsed into frozen dataclasses.

Defaults are the paper's parameter table (Fernando & Liu, Table I), written here once.
Unknown keys and out-of-range values raise :class:`ConfigError` naming the dotted key.
Paths in a config are relative to the config file. ``--set a.b=v`` overrides any key.
A key renamed since an earlier version (:data:`RENAMED_KEYS`) still loads under its new
name, with a :class:`~mrfswarm.errors.DeprecatedKeyWarning`.
"""

from __future__ import annotations

import dataclasses
import math
import os
import tomllib
import warnings
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any, get_args, get_origin, get_type_hints

import numpy as np

from mrfswarm.errors import ConfigError, DeprecatedKeyWarning
from mrfswarm.file_input import read_text
from mrfswarm.maps import LOADERS
from mrfswarm.trajectory.problem import DEFAULT_DEGREE, DEFAULT_DERIVATIVE
from mrfswarm.trajectory.uav_csv import DEGREE as EXPORT_DEGREE
from solvers.mrf import METHODS as MRF_METHODS
from solvers.mrf import Options as MRFOptions
from solvers.nlp import BACKENDS as NLP_BACKENDS
from solvers.nlp import Options as NLPOptions
from solvers.qp import Options as QPOptions

SEAM_MODES = ("rest", "continuous")
#: How ``smoothing.time_refinement`` shortens a window's durations (:mod:`mrfswarm.continuous.duration_scaling`,
#: or the NLP backend ``smoothing.nlp``).
REFINEMENTS = ("scaling", "nlp")
#: What resets the discrete stage's patience (see :func:`mrfswarm.discrete.planner.plan_discrete`).
PROGRESS_RULES = ("static", "energy")
#: How the goal potential measures the distance to the goal (see :mod:`mrfswarm.discrete.potentials`).
GOAL_DISTANCES = ("geodesic", "euclidean")
#: Who gets a cell several robots could move to (see :func:`mrfswarm.discrete.label_sets.label_sets`; ``"auto"``
#: plans with each of :data:`mrfswarm.discrete.planner.AUTO_RULES` and keeps the plan that flies soonest; "queue"
#: has the label sets of "shared").
CONTESTED_RULES = ("auto", "shared", "queue", "downhill", "nearest")

#: Keys of earlier versions, and what replaced them.
REMOVED_KEYS = {
    "smoothing.corridor": "trajectories now fly in safe regions around the discrete moves "
                          "(smoothing.region_growth sets their size)",
    "smoothing.safety_distance": "the safety distance is twice scenario.robot_radius (metres)",
}
#: Keys of earlier versions that still load, and their current names (in the same section).
RENAMED_KEYS = {
    "mrf.optimizer": "mrf.method",  # the name solvers.mrf.minimize(method=) and plan_discrete(method=) use
}
#: Optional tables of solver options and the options class whose fields they may set. The
#: config holds the fields given; the stage that solves puts them over its own options.
SOLVER_OPTIONS: dict[str, type] = {
    "mrf.options": MRFOptions,
    "smoothing.qp_options": QPOptions,
    "smoothing.nlp_options": NLPOptions,
}


@dataclass(frozen=True)
class ScenarioConfig:
    """The map, the start swarm, the goal (metres, map frame) and the flight altitude.

    Points have one number per axis of the map: ``[x, y]`` on a 2-D map, whose robots fly
    at z = ``altitude``; ``[x, y, z]`` on a 3-D (voxel) map, where z comes from the map's
    frame and ``altitude`` is not used.

    ``map`` and ``start`` are tables checked by :func:`mrfswarm.maps.load_map` and
    :func:`mrfswarm.discrete.start.start_cells`; ``robot_radius`` (metres, below half a cell) is
    each robot's size: trajectories keep it from obstacles and twice it (the safety
    distance) from each other; ``goal_radius`` defines "reached the goal":
    the swarm's centroid within this many metres of the goal (unset: 3 cells, 3 m at the
    paper's 1 m cells; :func:`mrfswarm.scenario.goal_radius_m`). A robot is *at the goal*
    within ``goal_radius`` plus the free-path radius that holds 4 free cells per robot
    (:mod:`mrfswarm.discrete.robot_outcomes`). Without a goal there is no
    goal potential (the paper's free-space formation experiments, rho_S = 0 there).
    ``downwash`` = c >= 1 stretches each robot along z (3-D maps): two robots are apart when
    sqrt(dx^2 + dy^2 + (dz / c)^2) >= 2 robot_radius, and the discrete plan keeps them one cell
    apart in that scaled metric (no effect on a 2-D map).
    """

    map: dict = field(default_factory=lambda: {"kind": "free", "size": [20, 20]})
    start: dict = field(default_factory=lambda: {"center": [5.0, 5.0], "n_robots": 5, "seed": 0})
    goal: tuple[float, ...] | None = None
    goal_radius: float | None = None
    altitude: float = 1.0
    robot_radius: float = 0.25
    downwash: float = 1.0


@dataclass(frozen=True)
class InteractionConfig:
    """Morse interaction potential and the k-nearest-neighbour graph.

    rho'_I(d) = -a exp(-d / k_a) + b exp(-d / k_r); rho_I = rho'_I + zeta. ``zeta``
    ``None`` means 1.01 |rho'_I(d_min)|, the smallest round value the paper allows.
    ``k_a`` and ``k_r`` are in cells, as the paper's table is at its 1 m cells (d_min =
    8.42 cells; :mod:`mrfswarm.discrete.potentials`).
    """

    a: float = 0.7
    b: float = 0.9
    k_a: float = 14.0
    k_r: float = 4.0
    k: int = 3
    zeta: float | None = None


#: The default ``goal_potential.congestion`` with the geodesic distance (flight_quality bench: 200 robots in 15 %
#: clutter all at the goal, 3.2 x the bound, against 164 of 200 at 4.1 x without; see mrfswarm.discrete.congestion).
CONGESTION = 8.0


@dataclass(frozen=True)
class GoalPotentialConfig:
    """rho_G(p) = a exp(d(p) / k), ``k`` in cells (20 m at the paper's 1 m cells).

    ``distance`` is how d is measured: ``"geodesic"`` (default), the length of the
    shortest free path to the goal, with the obstacle potential climbed on the way
    counted too, so that the static field has no local minimum but the goal and the swarm
    gets around concave obstacles and through doorways; ``"euclidean"``, the paper's
    straight-line |p - p_g|, under which every concave obstacle facing the swarm is a
    local minimum (kept for the paper's scenarios and the ablation).

    ``congestion`` w prices the swarm's own jams into the geodesic distance: every
    ``congestion_every`` steps the distance is searched again with a move into a cell
    crowded by stalled robots costing up to 1 + w times its length, so that robots behind
    a jam take another gap (:mod:`mrfswarm.discrete.congestion`). Unset, it is
    :data:`CONGESTION` with the geodesic distance and 0 (off) with the euclidean one,
    which it cannot reshape.
    """

    a: float = 3.0
    k: float = 20.0
    distance: str = "geodesic"
    congestion: float | None = None
    congestion_every: int = 5

    @property
    def congestion_weight(self) -> float:
        """w in force: ``congestion``, or its default for the distance."""
        if self.congestion is not None:
            return float(self.congestion)
        return CONGESTION if self.distance == "geodesic" else 0.0


#: The default ``obstacle_potential.gamma`` (the paper's table: 5). Measured (flight_quality bench, defaults,
#: makespan over the bound, 5 -> 2): 40 robots on 64 x 64 with 10 % clutter, seven maps, mean 1.92 -> 1.66 in
#: 86 -> 76 MRF steps, stops 0.82 -> 0.54 per robot; 200 robots in 15 % clutter 2.71 -> 2.49; 3 and 1.5 did less.
GAMMA = 2.0


@dataclass(frozen=True)
class ObstaclePotentialConfig:
    """m_hat = gamma where P(occupied) >= 0.5, blurred by a Gaussian of ``sigma`` cells.

    ``gamma`` defaults to :data:`GAMMA`, not the paper's 5 (its scenario configs set 5):
    the geodesic goal field counts the obstacle potential a path climbs as k_G / a_G metres
    per unit (:mod:`mrfswarm.discrete.goal_distance`), so with 5 a cell beside a lone
    obstacle cell costs about 3 m more than its length, and in clutter the swarm weaves
    around single cells at that price.
    """

    gamma: float = GAMMA
    sigma: float = 1.0


@dataclass(frozen=True)
class MrfConfig:
    """The discrete stage: MRF method, search order n, stopping.

    ``method`` is a name of ``solvers.mrf.METHODS`` (``--mrf NAME`` is a shorthand for
    ``--set mrf.method=NAME``); ``options`` (the table ``[mrf.options]``) sets fields of
    :class:`solvers.mrf.Options` (``max_iter``, ``tol``, ``time_limit``, ...) for every
    step's run of it.

    A step's label set is the free cells with dx^2 + dy^2 <= ``order``. The planner stops
    when one optimizer run lowers the swarm energy by less than ``tol`` times its value
    (relative: converged), when the swarm energy has made no new minimum for ``patience``
    steps (stalled: the k-NN graph changes as the swarm moves, so the dynamics need not
    settle), or after ``max_steps`` steps. ``trim_backward`` (default true) drops candidate cells that point
    away from the goal (the paper's optional heuristic; its scenario configs set false): with the geodesic
    goal field, the moves that raise a robot's free-path distance to the goal by more than ``trim_slack``
    cells (default 0.5: a sideways move, square to the way, raises it by 0.41-0.59 cell on the 8-connected
    grid, up to 0.68 on voxels, and the paper's dot-product rule keeps it; 0 trimmed those too and left 3 of 1000 robots crossing
    an open field outside the goal after 300 steps), except for a robot that has stayed in its cell for the
    last ``trim_escape`` steps (default 2; 0: never), which gets its whole label set back: trimmed alone, a
    crowd loses the moves that make room and strands robots (docs/flight_quality.md, "What changed").
    ``contested`` says who may move to a cell several robots could move to: the paper
    gives it to one robot, the nearest, and among equally near ones ``"downhill"``
    to the one whose static field it lowers most, ``"nearest"`` to the lower index (the
    paper's scenario configs), which can lock a crowd up in a corridor; ``"shared"`` keeps it
    for all of them, the step MRF's hard conflicts deciding who takes it (faster through
    clutter and aisles, slower and not all arrived on big straight crossings;
    :mod:`mrfswarm.discrete.label_sets`); ``"queue"`` is ``"shared"`` with the robots that have
    waited longest in their cells visited first by the step's optimizer, so of two robots that
    need a cell the one that waited takes it (a robot beside a moving file merges into its gaps
    instead of waiting for its end). ``"auto"`` (default) plans with ``"downhill"``, ``"shared"``
    and, where the robots of the ``"shared"`` plan wait a quarter of a step each or more, ``"queue"``,
    and keeps the plan with the most robots at the goal, then the one the time grid's model flies
    soonest (:func:`mrfswarm.discrete.planner.plan_discrete`); the discrete stage costs two to three
    times as much, a small part of a run with smoothing.
    ``follow`` (default true) lets a robot take the cell another robot leaves in the
    same step, when their moves keep them one cell apart (a queue moves as a whole);
    false is the paper's rule (cells where robots stand are no candidates), set by the
    paper's scenario configs.
    ``arrival`` (default true) ends the plan at the first step with every robot in the
    goal region (stop reason ``"arrived"``); false lets the swarm settle into its
    formation until the energy converges, as the paper does (its scenario configs).
    ``merge_waits`` (default true) moves each wait that cuts a robot's run of moves to the
    run's end once the paths are planned, where safe (same cells, same order; fewer stops
    and starts to fly, :mod:`mrfswarm.discrete.merge_waits`); false keeps the MRF's timing,
    as the paper's scenario configs do.
    ``drop_loops`` (default true) makes a robot that comes back to a cell it left wait there
    instead, where it stays one cell from every other robot (its cells a subsequence of
    the MRF's; no reversal to fly, :mod:`mrfswarm.discrete.loops`); false keeps the MRF's
    paths, as the paper's scenario configs do.
    ``straighten`` (default true) then shortens each robot's way between two of its steps
    (at most 8 apart) where safe: the same ends and step count, no move longer, a wait still a
    wait (two diagonal moves that zigzag become two straight ones; :mod:`mrfswarm.discrete.straighten`);
    false keeps the MRF's cells, as the paper's scenario configs do.
    ``escalation`` (default ``"trws"``): a step that the plan's method leaves without progress
    short of the goal (no robot moved, or the energy fell by less than ``tol``) is solved again
    by this method over the same step MRF, and its solution taken if it moves robots to a lower
    energy: ICM, which moves one robot at a time, leaves two robots that each wait for the other's
    cell (a one-voxel window under downwash) where a joint solution steps one aside. ``"none"``:
    the plan ends there, as the paper's (its scenario configs).
    ``progress`` says what resets the patience: ``"static"`` (default), a new minimum of
    the swarm energy or of the robots' static field sum; ``"energy"``, of the swarm
    energy only (the paper's scenario configs), which jumps whenever the k-NN graph's
    cliques change and so can stall a large swarm that is still on its way.
    """

    method: str = "icm"
    order: int = 2
    max_steps: int = 300
    tol: float = 1e-6
    patience: int = 20
    trim_backward: bool = True
    trim_escape: int = 2
    trim_slack: float = 0.5
    contested: str = "auto"
    follow: bool = True
    arrival: bool = True
    merge_waits: bool = True
    drop_loops: bool = True
    straighten: bool = True
    escalation: str = "trws"
    progress: str = "static"
    options: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class SmoothingConfig:
    """The continuous stage (min-snap smoothing on safe regions in a receding horizon).

    The step durations of the common time grid come from the robots' motion and the
    limits (each robot near ``v_max`` on a straight run, slower into turns and waits;
    :func:`mrfswarm.continuous.time_grid.motion_durations`); ``speed`` (m/s), when given,
    sets them instead from each step's longest move at that cruise speed (the earlier default, 1.25);
    ``region_growth`` (cells) how far each robot's obstacle-free box may grow around its
    discrete move; ``horizon`` steps are planned per window and ``execution`` of them
    flown; ``seam`` is ``continuous`` (continuous up to jerk across windows) or ``rest``
    (the paper's: every executed part from rest to rest). ``v_max``/``a_max``/``j_max``
    (m/s, m/s^2, m/s^3) are limits every trajectory meets, proven on control points; the
    jerk limit bounds how far a tracking controller lags (see :mod:`mrfswarm.simulation`).
    ``time_refinement`` re-optimizes each window's step durations for snap +
    ``time_weight`` x flight time (snap units per second, per robot): with ``refinement =
    "scaling"`` (the default) by a few QP solves that rescale each step by its multipliers
    (:mod:`mrfswarm.continuous.duration_scaling`), with ``"nlp"`` by ``nlp``, a name
    of ``solvers.nlp.BACKENDS`` (``--nlp NAME`` is a shorthand for ``--set smoothing.nlp=NAME --set
    smoothing.refinement=nlp``). ``check_rate_hz`` > 0
    adds an independent sampled check of the whole flight at that rate. ``qp_options`` (the
    table ``[smoothing.qp_options]``) sets fields of :class:`solvers.qp.Options`
    (``eps_abs``, ``eps_rel``, ``max_iter``, ...) over the stage's own for every QP solve;
    ``nlp_options`` (``[smoothing.nlp_options]``) sets fields of :class:`solvers.nlp.Options` (``tol``,
    ``max_iter``, ``time_limit``, ``verbose``) over the time refinement's own (``tol = 1e-4``, ``max_iter = 12``:
    :data:`mrfswarm.continuous.receding_horizon.NLP_OPTIONS`) for every NLP solve of ``refinement = "nlp"``.
    ``max_pieces`` > 0 caps each robot's polynomial pieces (a Crazyflie holds 31): a flight of
    more steps flies several steps per piece where needed (0: one piece per step; see
    :mod:`mrfswarm.continuous.merge_pieces`).
    """

    enabled: bool = True
    # the continuous stage's default QP backend, written only here (a bare QP without a
    # backend goes to solvers.qp.DEFAULT_BACKEND)
    backend: str = "piqp"
    degree: int = DEFAULT_DEGREE
    derivative: int = DEFAULT_DERIVATIVE
    speed: float | None = None
    region_growth: float = 1.0
    horizon: int = 8
    execution: float = 0.5
    seam: str = "continuous"
    time_refinement: bool = False
    refinement: str = "scaling"
    # the time refinement's NLP backend, written only here
    nlp: str = "ipopt"
    time_weight: float = 20.0
    v_max: float = 2.0
    a_max: float = 4.0
    j_max: float = 4.0
    check_rate_hz: float = 0.0
    max_pieces: int = 31
    qp_options: dict[str, Any] = field(default_factory=dict)
    nlp_options: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class SimulationConfig:
    """Closed-loop quadrotor simulation of every robot (RotorPy).

    ``backend``: "auto" (batched when torch is installed), "batched" (one vectorized
    simulation of the swarm) or "processes" (one simulation per robot, in parallel
    processes); see :mod:`mrfswarm.simulation`.
    """

    enabled: bool = True
    vehicle: str = "crazyflie"
    rate_hz: float = 100.0
    backend: str = "auto"


@dataclass(frozen=True)
class Config:
    """A whole experiment. ``base_dir`` is where relative paths are resolved.

    Made by :func:`load_config` (a TOML file, ``--set`` overrides) or :func:`from_dict` (the same tables as
    Python data), which check every key. Changed with :meth:`replace` and ``dataclasses.replace`` of a section
    (``cfg.replace(smoothing=dataclasses.replace(cfg.smoothing, v_max=1.0))``); :func:`mrfswarm.plan` checks
    such a config again (:func:`validated`).
    """

    scenario: ScenarioConfig = field(default_factory=ScenarioConfig)
    interaction: InteractionConfig = field(default_factory=InteractionConfig)
    goal_potential: GoalPotentialConfig = field(default_factory=GoalPotentialConfig)
    obstacle_potential: ObstaclePotentialConfig = field(default_factory=ObstaclePotentialConfig)
    mrf: MrfConfig = field(default_factory=MrfConfig)
    smoothing: SmoothingConfig = field(default_factory=SmoothingConfig)
    simulation: SimulationConfig = field(default_factory=SimulationConfig)
    base_dir: Path = field(default=Path("."), compare=False)

    def replace(self, **sections: Any) -> Config:
        """A copy with whole sections replaced (``cfg.replace(mrf=...)``)."""
        return dataclasses.replace(self, **sections)

    def to_dict(self) -> dict:
        """The config as plain TOML-able data (``base_dir`` left out)."""
        d = dataclasses.asdict(self)
        d.pop("base_dir")
        return d


_SECTIONS = {f.name: f.type for f in fields(Config) if f.name != "base_dir"}


def _section_types() -> dict[str, type]:
    hints = get_type_hints(Config)
    return {name: hints[name] for name in _SECTIONS}


#: Characters of a wrong value a message shows: a map given as an array of 60 x 40 cells was refused in a message of
#: 17,000 characters, the whole array (a library tour).
SHOWN_CHARS = 80


def _shown(value: Any) -> str:
    """``repr(value)``, cut to :data:`SHOWN_CHARS` characters."""
    text = repr(value)
    return text if len(text) <= SHOWN_CHARS else f"{text[:SHOWN_CHARS - 3]}..."


def _coerce(key: str, value: Any, hint: Any) -> Any:
    """Check ``value`` against the annotation ``hint``; return it in the field's type."""
    origin = get_origin(hint)
    args = get_args(hint)
    if origin is None and hint is type(None):
        if value is not None:
            raise ConfigError(f"{key} must be empty, got {_shown(value)}")
        return None
    if args and type(None) in args:  # Optional[X]
        if value is None:
            return None
        inner = [a for a in args if a is not type(None)]
        return _coerce(key, value, inner[0])
    if hint is bool:
        if not isinstance(value, bool):
            raise ConfigError(f"{key} must be true or false, got {_shown(value)}")
        return value
    if hint is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(f"{key} must be an integer, got {_shown(value)}")
        return value
    if hint is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(f"{key} must be a number, got {_shown(value)}")
        if not math.isfinite(value):
            raise ConfigError(f"{key} must be finite, got {_shown(value)}")
        return float(value)
    if hint is str:
        if not isinstance(value, str):
            raise ConfigError(f"{key} must be a string, got {_shown(value)}")
        return value
    if hint is dict or origin is dict:
        if not isinstance(value, dict):
            # an occupancy array built in code (as data, it is a list of lists by now) is a map file's content
            array = ('; an occupancy array is read from a file: numpy.save it and give {"kind": "npy", "path": ...}'
                     if key == "scenario.map" and isinstance(value, list) else "")
            raise ConfigError(f"{key} must be a table, got {_shown(value)}{array}")
        return value
    if origin is tuple and len(args) == 2 and args[1] is Ellipsis:  # tuple[X, ...]: any length, checked later
        if not isinstance(value, (list, tuple)):
            raise ConfigError(f"{key} must be a list of numbers, got {_shown(value)}")
        return tuple(_coerce(f"{key}[{i}]", v, args[0]) for i, v in enumerate(value))
    if origin is tuple:
        if not isinstance(value, (list, tuple)) or len(value) != len(args):
            raise ConfigError(f"{key} must be a list of {len(args)} numbers, got {_shown(value)}")
        return tuple(_coerce(f"{key}[{i}]", v, args[i]) for i, v in enumerate(value))
    raise TypeError(f"unsupported config annotation {hint!r} for {key}")  # a bug in this module, not user input


def current_key(key: str) -> str:
    """The dotted config ``key`` under its current name; an old name warns (:data:`RENAMED_KEYS`)."""
    new = RENAMED_KEYS.get(key)
    if new is None:
        return key
    warnings.warn(f"config key {key} is now {new}; {key} still loads, as {new}", DeprecatedKeyWarning, stacklevel=2)
    return new


def _current_names(data: dict) -> dict:
    """TOML data with its renamed keys under their current names (warning once for each)."""
    out = dict(data)
    for old, new in RENAMED_KEYS.items():
        section, key = old.split(".")
        table = out.get(section)
        if not isinstance(table, dict) or key not in table:
            continue
        if new.split(".")[1] in table:
            raise ConfigError(f"{old} and {new} are both given; {old} is the old name of {new}: keep {new}")
        table = dict(table)
        table[current_key(old).split(".")[1]] = table.pop(key)
        out[section] = table
    return out


def _build_section(name: str, cls: type, table: Any) -> Any:
    if not isinstance(table, dict):
        raise ConfigError(f"[{name}] must be a table, got {table!r}")
    hints = get_type_hints(cls)
    known = {f.name for f in fields(cls)}
    for key in table:
        if f"{name}.{key}" in REMOVED_KEYS:
            raise ConfigError(f"config key {name}.{key} was removed: {REMOVED_KEYS[f'{name}.{key}']}")
        if key not in known:
            raise ConfigError(f"unknown config key {name}.{key}; allowed: {', '.join(sorted(known))}")
    values = {k: _solver_options(f"{name}.{k}", v) if f"{name}.{k}" in SOLVER_OPTIONS
              else _coerce(f"{name}.{k}", v, hints[k]) for k, v in table.items()}
    return cls(**values)


def _solver_options(key: str, table: Any) -> dict[str, Any]:
    """The fields a table of :data:`SOLVER_OPTIONS` gives, each checked against its annotation."""
    if not isinstance(table, dict):
        raise ConfigError(f"{key} must be a table, got {table!r}")
    cls = SOLVER_OPTIONS[key]
    hints = get_type_hints(cls)
    known = [f.name for f in fields(cls)]
    for k in table:
        if k not in known:
            raise ConfigError(f"unknown config key {key}.{k}; allowed: {', '.join(known)}")
    return {k: _coerce(f"{key}.{k}", v, hints[k]) for k, v in table.items()}


def check_nlp(name: str) -> None:
    """``smoothing.nlp`` must name a backend of ``solvers.nlp.BACKENDS`` (installed or not).

    Raises
    ------
    ConfigError
        Naming the value and the allowed ones.
    """
    if name not in NLP_BACKENDS:
        raise ConfigError(f"smoothing.nlp = {name!r}: must be one of {', '.join(NLP_BACKENDS.names())}")


#: Upper bounds of keys whose huge values exhausted the memory or hung instead of failing (a robustness tour,
#: 2026-11-29): scenario.altitude 1e300 overflowed the Crazyflie packing; scenario.downwash 1000 took 7.5 GB on a
#: small voxel map; obstacle_potential.sigma and mrf.order 1e11 ran out of memory (mrf.order 100: 7.3 GB, 29 s on the
#: corridor; 32: 0.3 GB, 1.6 s); smoothing.region_growth 1e11 hung; smoothing.check_rate_hz 1e11 ran out of memory
#: after the discrete stage. Each bound is far past any use (a sigma or growth of 1000 cells: 2 s on the corridor).
MAX_ALTITUDE = 1e4  # m
MAX_DOWNWASH = 20.0
MAX_CELLS = 1000  # obstacle_potential.sigma, smoothing.region_growth
MAX_ORDER = 32  # cells²
MAX_CHECK_RATE_HZ = 1e4


def _validate(cfg: Config) -> None:
    """Range checks that do not need the map (those live with the map and the planner)."""

    def need(cond: bool, key: str, value: Any, what: str) -> None:
        if not cond:
            raise ConfigError(f"{key} = {value!r}: {what}")

    s = cfg.scenario
    kind = s.map.get("kind")
    need(kind in LOADERS, "scenario.map.kind", kind, f"must be one of {', '.join(LOADERS)}")
    need(s.goal is None or len(s.goal) in (2, 3), "scenario.goal", None if s.goal is None else list(s.goal),
         "must be [x, y] or, on a 3-D map, [x, y, z] (metres)")
    need(s.goal_radius is None or s.goal_radius > 0, "scenario.goal_radius", s.goal_radius, "must be > 0 (metres)")
    need(0 < s.altitude <= MAX_ALTITUDE, "scenario.altitude", s.altitude, f"must be in (0, {MAX_ALTITUDE:g}] (metres)")
    need(s.robot_radius > 0, "scenario.robot_radius", s.robot_radius, "must be > 0 (metres)")
    need(1 <= s.downwash <= MAX_DOWNWASH, "scenario.downwash", s.downwash,
         f"must be in [1, {MAX_DOWNWASH:g}] (a Crazyflie's is about 2)")
    i = cfg.interaction
    need(i.k >= 1, "interaction.k", i.k, "must be >= 1")
    # the paper's Morse conditions and zeta, where the potential is defined (one place); imported
    # here because the potentials module reads this one's dataclasses
    from mrfswarm.discrete.potentials import Morse

    Morse.from_config(i)
    g = cfg.goal_potential
    need(g.a > 0, "goal_potential.a", g.a, "must be > 0")
    need(g.k > 0, "goal_potential.k", g.k, "must be > 0")
    need(g.distance in GOAL_DISTANCES, "goal_potential.distance", g.distance, f"must be one of {', '.join(GOAL_DISTANCES)}")
    need(g.congestion is None or (math.isfinite(g.congestion) and g.congestion >= 0), "goal_potential.congestion",
         g.congestion, "must be >= 0 (0: the static field)")
    need(not (g.congestion and g.distance != "geodesic"), "goal_potential.congestion", g.congestion,
         'needs goal_potential.distance = "geodesic" (it reshapes the free-path distance)')
    need(g.congestion_every >= 1, "goal_potential.congestion_every", g.congestion_every, "must be >= 1 (steps)")
    o = cfg.obstacle_potential
    need(o.gamma > 0, "obstacle_potential.gamma", o.gamma, "must be > 0")
    need(0 <= o.sigma <= MAX_CELLS, "obstacle_potential.sigma", o.sigma, f"must be in [0, {MAX_CELLS}] (cells)")
    m = cfg.mrf
    need(1 <= m.order <= MAX_ORDER, "mrf.order", m.order, f"must be in 1..{MAX_ORDER} (cells²: moves of up to "
         f"{math.isqrt(MAX_ORDER)} cells along an axis)")
    need(m.max_steps >= 1, "mrf.max_steps", m.max_steps, "must be >= 1")
    # a tol of 1 or more converged at the first step: no step lowers the energy by all of it (a tour)
    need(0 <= m.tol < 1, "mrf.tol", m.tol, "must be in [0, 1) (a fraction of the swarm energy)")
    need(m.patience >= 1, "mrf.patience", m.patience, "must be >= 1")
    need(m.trim_escape >= 0, "mrf.trim_escape", m.trim_escape, "must be >= 0")
    need(m.trim_slack >= 0, "mrf.trim_slack", m.trim_slack, "must be >= 0")
    need(m.progress in PROGRESS_RULES, "mrf.progress", m.progress, f"must be one of {', '.join(PROGRESS_RULES)}")
    need(m.contested in CONTESTED_RULES, "mrf.contested", m.contested, f"must be one of {', '.join(CONTESTED_RULES)}")
    escalations = ("none", *MRF_METHODS.names())
    need(m.escalation in escalations, "mrf.escalation", m.escalation, f"must be one of {', '.join(escalations)}")
    sm = cfg.smoothing
    need(sm.degree >= 3, "smoothing.degree", sm.degree, "must be >= 3 (jerk is bounded on control points)")
    # every run writes its flight as uav_trajectories CSV and Crazyflie pieces, which hold degree 7: a plan of a
    # higher degree would be planned in full and then not written
    need(sm.degree <= EXPORT_DEGREE, "smoothing.degree", sm.degree,
         f"must be <= {EXPORT_DEGREE} (the uav_trajectories CSV and the Crazyflie hold degree {EXPORT_DEGREE})")
    need(1 <= sm.derivative <= (EXPORT_DEGREE + 1) // 2, "smoothing.derivative", sm.derivative,
         f"must be in 1..{(EXPORT_DEGREE + 1) // 2} (the degree, at most {EXPORT_DEGREE}, must be >= 2 x derivative - 1)")
    need(sm.degree >= 2 * sm.derivative - 1, "smoothing.degree", sm.degree,
         f"must be >= 2 * smoothing.derivative - 1 = {2 * sm.derivative - 1}")
    need(sm.speed is None or sm.speed > 0, "smoothing.speed", sm.speed, "must be > 0 (or left out: from the limits)")
    need(0 <= sm.region_growth <= MAX_CELLS, "smoothing.region_growth", sm.region_growth,
         f"must be in [0, {MAX_CELLS}] (cells)")
    need(sm.horizon >= 1, "smoothing.horizon", sm.horizon, "must be >= 1")
    need(0 < sm.execution <= 1, "smoothing.execution", sm.execution, "must be in (0, 1]")
    need(sm.seam in SEAM_MODES, "smoothing.seam", sm.seam, f"must be one of {', '.join(SEAM_MODES)}")
    need(sm.time_weight > 0, "smoothing.time_weight", sm.time_weight, "must be > 0")
    need(sm.refinement in REFINEMENTS, "smoothing.refinement", sm.refinement, f"must be one of {', '.join(REFINEMENTS)}")
    check_nlp(sm.nlp)
    need(sm.check_rate_hz == 0 or 100 <= sm.check_rate_hz <= MAX_CHECK_RATE_HZ, "smoothing.check_rate_hz",
         sm.check_rate_hz, f"must be 0 (off) or in [100, {MAX_CHECK_RATE_HZ:g}] (Hz)")
    need(sm.max_pieces >= 0, "smoothing.max_pieces", sm.max_pieces, "must be >= 0 (0: one piece per step)")
    need(sm.v_max > 0, "smoothing.v_max", sm.v_max, "must be > 0")
    need(sm.speed is None or sm.speed <= sm.v_max, "smoothing.speed", sm.speed,
         f"must be <= smoothing.v_max = {sm.v_max:g} (a cruise above the speed limit has no solution)")
    need(sm.a_max > 0, "smoothing.a_max", sm.a_max, "must be > 0")
    need(sm.j_max > 0, "smoothing.j_max", sm.j_max, "must be > 0")
    for key, cls in SOLVER_OPTIONS.items():  # the options class's own range checks
        section, name = key.split(".")
        try:
            cls(**getattr(getattr(cfg, section), name))
        except ValueError as e:
            raise ConfigError(f"{key}: {e}") from None
    need(cfg.simulation.rate_hz >= 100, "simulation.rate_hz", cfg.simulation.rate_hz, "must be >= 100")
    need(cfg.simulation.backend in ("auto", "batched", "processes"), "simulation.backend", cfg.simulation.backend,
         "must be one of auto, batched, processes")


def from_dict(data: dict, base_dir: Path | str = ".") -> Config:
    """Build and validate a :class:`Config` from TOML-shaped data.

    Raises
    ------
    ConfigError
        Unknown key, wrong type or out-of-range value; the message names the key.
    """
    if not isinstance(data, dict):  # a list gave "cannot convert dictionary update sequence element #0 to a sequence"
        raise ConfigError(f"a config's data is a table of sections ({{'scenario': {{...}}, ...}}), got "
                          f"{type(data).__name__} {data!r:.60}")
    types = _section_types()
    data = _current_names(_plain(data))
    for key in data:
        if key not in types:
            raise ConfigError(f"unknown config section {key!r}; allowed: {', '.join(types)}")
    sections = {name: _build_section(name, cls, data.get(name, {})) for name, cls in types.items()}
    n = _start_size(sections["scenario"].start)
    if "k" not in data.get("interaction", {}) and n is not None and 2 <= n <= sections["interaction"].k:
        # the default k = 3 needs 4 robots: a swarm of 2 or 3 with k unset gets N - 1, every other robot
        sections["interaction"] = dataclasses.replace(sections["interaction"], k=n - 1)
    cfg = Config(**sections, base_dir=Path(base_dir))
    _validate(cfg)
    return cfg


def validated(cfg: Config) -> Config:
    """``cfg`` checked as :func:`load_config` checks a file (types, ranges, unknown keys), as a new :class:`Config`.

    A config changed in code (``cfg.replace(...)`` with ``dataclasses.replace`` of a section, or ``Config(...)``
    built by hand) skips the checks :func:`from_dict` makes; :func:`mrfswarm.plan` runs them again through this.

    Raises
    ------
    ConfigError
        Naming the dotted key and the bad value.
    """
    if not isinstance(cfg, Config):
        raise ConfigError(f"expected a Config, got {type(cfg).__name__} {cfg!r:.60}")
    try:
        data = cfg.to_dict()
    except TypeError as e:  # a section that is not a dataclass nor a dict (asdict cannot copy it)
        raise ConfigError(f"a Config's sections are its dataclasses (or tables): {e}") from None
    return from_dict(data, cfg.base_dir)


def _start_size(start: Any) -> int | None:
    """The number of robots a ``scenario.start`` table gives (None if it does not say, or says it wrongly: the
    scenario's own checks name that)."""
    if not isinstance(start, dict):
        return None
    if "positions" in start:
        return len(start["positions"]) if isinstance(start["positions"], list) else None
    n = start.get("n_robots")
    return n if isinstance(n, int) and not isinstance(n, bool) else None


def _plain(value: Any) -> Any:
    """``value`` with NumPy arrays and scalars as the lists and numbers TOML gives (a start of positions built
    with NumPy was refused in a message of six lines, ``interaction.k = np.int64(2)`` as not an integer)."""
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return type(value)(_plain(v) for v in value)
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    return value


def parse_override(item: str) -> tuple[list[str], Any]:
    """Parse ``a.b.c=VALUE``; VALUE is a TOML literal, or a bare string if it is not one."""
    if "=" not in item:
        raise ConfigError(f"--set {item!r}: expected KEY=VALUE")
    key, raw = item.split("=", 1)
    path = key.strip().split(".")
    if not all(path):
        raise ConfigError(f"--set {item!r}: empty key")
    try:
        value = tomllib.loads(f"v = {raw.strip()}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw.strip()
    return path, value


def apply_overrides(data: dict, overrides: list[str]) -> dict:
    """Apply ``--set`` overrides to TOML data (nested tables created as needed).

    A renamed key sets its current name (:func:`current_key`), so that ``--set
    mrf.optimizer=gibbs`` overrides ``method`` in a config that gives it; overrides that give
    both names, as a file that does, are an error.

    A key of a table the config leaves to its default (``scenario.map``, ``scenario.start``) that
    the default table has sets it in that table: ``--set scenario.map.size=[12,12]`` is a free
    12 x 12 map, ``--set scenario.start.n_robots=6`` six robots around the default centre. A key
    the default lacks starts a table of its own (``scenario.start.positions``), and so does another
    ``kind`` than the default's (``--set scenario.map.kind=ascii`` is an ASCII map, whose rows are asked
    for, not one that also has the free map's ``size``).
    """
    data = _deepcopy(data)
    defaults = Config().to_dict()
    named: dict[str, str] = {}  # current key -> the name an override gave it by
    for item in overrides:
        path, value = parse_override(item)
        given = ".".join(path)
        key = current_key(given)
        other = named.setdefault(key, given)
        if other != given:
            old, new = (other, given) if other in RENAMED_KEYS else (given, other)
            raise ConfigError(f"{old} and {new} are both given; {old} is the old name of {new}: keep {new}")
        path = key.split(".")
        node = data
        default: Any = defaults
        for depth, part in enumerate(path[:-1]):
            default = default.get(part) if isinstance(default, dict) else None
            # a dict-valued key of a section (sections themselves get their defaults in from_dict)
            # (another ``kind`` than the default's starts a table of its own: the default's keys are another kind's)
            if part not in node and depth == len(path) - 2 >= 1 and isinstance(default, dict) and path[-1] in default \
                    and not (path[-1] == "kind" and default.get("kind") != value):
                node[part] = _deepcopy(default)
            nxt = node.setdefault(part, {})
            if not isinstance(nxt, dict):
                raise ConfigError(f"--set {item!r}: {part} is not a table")
            node = nxt
        node[path[-1]] = value
    return data


def _deepcopy(d: Any) -> Any:
    if isinstance(d, dict):
        return {k: _deepcopy(v) for k, v in d.items()}
    if isinstance(d, list):
        return [_deepcopy(v) for v in d]
    return d


def load_config(path: str | Path | None = None, overrides: list[str] | None = None) -> Config:
    """Read a TOML experiment config (or the defaults when ``path`` is None).

    Raises
    ------
    ConfigError
        Missing or unreadable file, TOML syntax error, unknown key, bad value.
    """
    data: dict = {}
    base = Path(".")
    if path is not None and not isinstance(path, (str, os.PathLike)):
        hint = "; from a dict: mrfswarm.config.from_dict(data)" if isinstance(path, dict) else ""
        raise ConfigError(f"a config is a path to a TOML file (or, to plan, a Config object), got "
                          f"{type(path).__name__} {path!r:.60}{hint}")
    if path is not None:
        p = Path(path)
        text = read_text(p, "config", ConfigError)
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as e:
            raise ConfigError(f"{p}: invalid TOML: {e}") from e
        base = p.resolve().parent
    data = _current_names(data)  # before the overrides, which set current names
    if isinstance(overrides, str):  # each character was read as an override ("--set 'i': expected KEY=VALUE")
        raise ConfigError(f"overrides = {overrides!r:.60}: a list of 'KEY=VALUE' strings, not one string")
    if overrides:
        data = apply_overrides(data, overrides)
    return from_dict(data, base)
