"""``plan``: a scenario config in; discrete paths, smooth certified trajectories, the flight and metrics out."""

from __future__ import annotations

import dataclasses
import functools
import logging
import numbers
import sys
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

import solvers.nlp
import solvers.qp
from mrfswarm.config import Config, check_nlp, load_config, validated
from mrfswarm.discrete.motion import cell_values
from mrfswarm.discrete.planner import SEPARATION_FACTOR, DiscretePlan, DiscreteProblem, plan_discrete
from mrfswarm.discrete.pruning import prune_paths
from mrfswarm.discrete.robot_outcomes import RobotOutcome, robot_outcomes
from mrfswarm.errors import (
    ConfigError,
    PlanError,
    PlanWarning,
    ScenarioError,
    SolverNotFound,
    SolversError,
    UnusedSettingWarning,
)
from mrfswarm.metrics import DiscreteMetrics, discrete_metrics
from mrfswarm.scenario import Scenario, build_scenario
from solvers import mrf as mrf_solvers
from solvers.registry import Backend, C, Registry

if TYPE_CHECKING:  # the continuous stage and the simulation are imported when they run
    from mrfswarm.continuous import ContinuousPlan
    from mrfswarm.simulation import SwarmFlight

log = logging.getLogger(__name__)


@dataclass
class Result:
    """Everything a run produced.

    Attributes
    ----------
    config
        The config used (after ``--set``/``--mrf``/``--seed`` overrides).
    scenario
        Map, start, goal, fields.
    discrete
        The discrete paths and per-step records.
    metrics
        Metrics of the discrete paths.
    pruned
        Per robot, step indices kept by the paper's waypoint pruning (per planning
        horizon; for figures and comparison: the continuous stage flies in safe regions
        around every discrete move instead of through pruned waypoints).
    continuous
        The smooth, certified trajectories (a
        :class:`~mrfswarm.continuous.ContinuousPlan`; None when smoothing is disabled or
        failed).
    flight
        The simulated quadrotors (None when the simulation is disabled or failed).
    timings_s
        Seconds per pipeline stage.
    failure
        The message of the error that stopped the run, if one did (the stages before it
        are kept).
    """

    config: Config
    scenario: Scenario
    discrete: DiscretePlan
    metrics: DiscreteMetrics
    pruned: list[np.ndarray]
    continuous: ContinuousPlan | None = None
    flight: SwarmFlight | None = None
    timings_s: dict[str, float] = field(default_factory=dict)
    failure: str | None = None
    _crazyflie: tuple | None = field(default=None, init=False, repr=False, compare=False)
    _quality: dict | None = field(default=None, init=False, repr=False, compare=False)

    def smoothed(self) -> ContinuousPlan:
        """The continuous plan of a run that has one.

        Raises
        ------
        ValueError
            When smoothing was disabled or failed.
        """
        if self.continuous is None:
            raise ValueError("this run has no continuous plan (smoothing disabled or failed)")
        return self.continuous

    def flown(self) -> SwarmFlight:
        """The simulated flight of a run that has one.

        Raises
        ------
        ValueError
            When the simulation was disabled or failed.
        """
        if self.flight is None:
            raise ValueError("this run has no simulated flight (simulation disabled or failed)")
        return self.flight

    @property
    def mrf(self) -> str:
        return self.config.mrf.method

    @property
    def qp(self) -> str | None:
        return self.config.smoothing.backend if self.config.smoothing.enabled else None

    @property
    def nlp(self) -> str | None:
        """The time refinement's NLP backend, None when no NLP refinement ran (none, or the multiplier scaling)."""
        sm = self.config.smoothing
        return sm.nlp if sm.enabled and sm.time_refinement and sm.refinement == "nlp" else None

    @property
    def smoothing_solvers(self) -> str | None:
        """The continuous stage's backends as the run's line and its trajectory figure name them: the QP backend, and
        the NLP backend where one refined the durations (``"piqp, refined by ipopt"``); None without the stage."""
        if self.qp is None:
            return None
        return self.qp if self.nlp is None else f"{self.qp}, refined by {self.nlp}"

    def robots(self) -> list[RobotOutcome]:
        """Where each robot ended and, if short of the goal region, why (:mod:`mrfswarm.discrete.robot_outcomes`)."""
        scn = self.scenario
        d = scn.distances
        return robot_outcomes(self.discrete.paths[-1], scn.grid.free, scn.static, self.config.mrf.order,
                              scn.grid.resolution, SEPARATION_FACTOR * scn.morse.d_min, self.discrete.stop_reason,
                              None if d is None else d.path, scn.goal_region_radius)

    def crazyflie_memory(self) -> dict | None:
        """The ``crazyflie`` section of ``result.json`` (:func:`mrfswarm.export.crazyflie_memory.memory_report`),
        computed once: each robot's pieces and bytes in a Crazyflie's memory, raw and compressed, and the
        compressed flight's certificate. None without a continuous plan."""
        return self._crazyflie_export()[0]

    def _crazyflie_export(self) -> tuple:
        """(the ``crazyflie`` section, the :class:`~mrfswarm.export.cflib_.Compressed` flight or None), cached."""
        if self._crazyflie is None:
            from mrfswarm.export.crazyflie_memory import memory_report

            self._crazyflie = memory_report(self)
        return self._crazyflie

    def flight_quality(self) -> dict | None:
        """The ``flight_quality`` section of ``result.json``, computed once (:mod:`mrfswarm.flight_quality`):
        the makespan over its lower bound (the longest shortest free path from a robot's start cell to its final
        cell, flown at ``v_max``), stops per robot and mean speeds. None without a continuous plan.

        Keys: ``lower_bound_s``, ``makespan_over_bound`` (None when no robot moves), ``bound_robot`` (the robot
        whose path sets the bound), ``stops_per_robot`` (mean), ``stops_max``, ``stops`` (per robot),
        ``stop_speed_m_s`` (the speed under which a robot counts as stopped), ``mean_speed_m_s`` (mean over
        robots of path length over flight time).
        """
        c = self.continuous
        if c is None:
            return None
        if self._quality is None:
            from mrfswarm import flight_quality as fq

            scn, paths = self.scenario, self.discrete.paths
            via = None if scn.distances is None else scn.distances.path
            lengths = fq.free_path_lengths(scn.grid.free, paths[0], paths[-1], scn.grid.resolution, via)
            longest = float(np.nanmax(lengths, initial=0.0))
            bound = longest / self.config.smoothing.v_max
            stops = fq.count_stops(c.trajectories)
            self._quality = {
                "lower_bound_s": bound,
                "makespan_over_bound": c.makespan_s / bound if bound > 0 else None,
                "bound_robot": int(np.nanargmax(lengths)) if longest > 0 else None,
                "stops_per_robot": stops.mean,
                "stops_max": int(stops.per_robot.max(initial=0)),
                "stops": [int(v) for v in stops.per_robot],
                "stop_speed_m_s": fq.STOP_SPEED,
                "mean_speed_m_s": float(stops.mean_speed.mean()) if stops.mean_speed.size else 0.0,
            }
        return self._quality

    def warnings(self) -> list[str]:
        """What this run warns of, one line each, in the order ``mrfswarm run`` prints them after its summary line
        (:func:`mrfswarm.run_warnings.run_warnings`); :func:`plan` issues each as a
        :class:`~mrfswarm.errors.PlanWarning`. Empty for a run with nothing to say."""
        from mrfswarm.run_warnings import run_warnings

        return run_warnings(self)

    def discrete_paths_world(self) -> np.ndarray:
        """(T + 1, N, d) discrete paths in metres (d = 3 on a voxel map: z from the map)."""
        return self.scenario.grid.cell_to_world(self.discrete.paths)

    def summary(self) -> dict:
        """The content of ``result.json``."""
        m = self.metrics
        g = self.scenario.goal_world
        c = self.continuous
        sm = self.config.smoothing
        robots = self.robots()
        grid = self.scenario.grid
        out = {
            "n_robots": self.scenario.n_robots,
            "mrf_steps": self.discrete.n_steps,
            "converged": self.discrete.converged,
            "stop_reason": self.discrete.stop_reason,
            "reached_goal": m.reached_goal,
            "goal": None if g is None else [float(v) for v in g],
            "final_goal_distance": m.final_goal_distance,
            "goal_region_radius_m": self.scenario.goal_region_radius,
            "goal_distance": self.config.goal_potential.distance,
            "robots_at_goal": None if g is None else sum(bool(r.at_goal) for r in robots),
            "robots_separated": sum(r.separated for r in robots),
            "robots": [{
                "robot": r.robot,
                "final": [float(v) for v in grid.cell_to_world(r.final_cell)],
                "goal_distance_m": r.goal_distance,
                "nearest_neighbour_m": _num(r.nearest_neighbour),
                "at_goal": r.at_goal,
                "separated": r.separated,
                "stop_reason": r.stop_reason,
                **({} if c is None else {"pieces": int(c.pieces_per_robot[r.robot])}),
            } for r in robots],
            "separation_threshold_m": SEPARATION_FACTOR * self.scenario.morse.d_min,
            "steps_with_separated_robots": int(sum(s.get("separated", 0) > 0 for s in self.discrete.steps)),
            "swarm_energy": [float(e) for e in self.discrete.energy],
            # both separations in the downwash-scaled metric (sqrt(dx^2 + dy^2 + (dz / c)^2); plain in 2-D)
            "downwash": self.config.scenario.downwash,
            "min_separation_discrete": _num(m.min_separation),
            "min_separation_continuous": None if c is None else _num(c.min_separation),
            "min_obstacle_clearance": _num(m.min_obstacle_clearance if c is None else c.min_clearance),
            "min_obstacle_clearance_discrete": _num(m.min_obstacle_clearance),
            "mean_inter_robot_distance_final": _num(m.mean_distance[-1]),
            "path_lengths": [float(v) for v in m.path_lengths],
            "makespan_s": None if c is None else c.makespan_s,
            "mrf": self.mrf,
            "qp": self.qp,
            "nlp": self.nlp,
            "mrf_order": self.config.mrf.order,
            "k": self.config.interaction.k,
            "pruned_waypoints": [int(len(p)) for p in self.pruned],
            "mrf_step_time_s": {k: float(np.mean(v)) if len(v) else 0.0 for k, v in self.discrete.timings.items()},
            "mrf_repaired": int(sum(s["repaired"] for s in self.discrete.steps)),
            "merged_waits": self.discrete.merged_waits,
            "dropped_loops": self.discrete.dropped_loops,
            "straightened": self.discrete.straightened,
            "escalated": self.discrete.escalated,
            "congested_fields": self.discrete.congested_fields,
            "congestion_weight": self.config.goal_potential.congestion_weight,
            "contested": self.discrete.contested,
            "timings_s": {k: float(v) for k, v in self.timings_s.items()},
            "failure": self.failure,
        }
        if c is not None:
            cert = c.certificate
            out.update({
                "seam": sm.seam,
                "robot_radius_m": self.config.scenario.robot_radius,
                "safety_distance_m": 2 * self.config.scenario.robot_radius,
                "limits": {"v_max": sm.v_max, "a_max": sm.a_max, "j_max": sm.j_max},
                "achieved": {"v_max": c.v_max, "a_max": c.a_max, "j_max": c.j_max},
                "certificate": {
                    "ok": cert.ok,
                    "separation_lower_bound_m": _num(cert.separation_bound),
                    "limit_upper_bounds": {"v": cert.limit_bounds[0], "a": cert.limit_bounds[1],
                                           "j": cert.limit_bounds[2]},
                    "near_pairs_checked": cert.near_pairs,
                    "clearance_lower_bound_m": self.config.scenario.robot_radius,
                },
                "pieces_per_robot": [int(p) for p in c.pieces_per_robot],
                "piece_limit": {
                    "max_pieces": c.max_pieces,
                    "fits": c.pieces_fit,
                    "robots_over": [i for i, p in enumerate(c.pieces_per_robot) if c.max_pieces and p > c.max_pieces],
                    "steps_per_piece_max": int(np.diff(c.piece_steps).max(initial=1)) if c.piece_steps is not None
                    else 1,
                },
                "windows": len(c.windows),
                "window_steps": c.horizon,  # smoothing.horizon, or more where the windows' tails brake from cruise
                "window_attempts": {name: sum(w.attempt == name for w in c.windows)
                                    for name in sorted({w.attempt for w in c.windows})},
                # why the windows flown as their witness had no other solution: each one's last rejected attempt
                "witness_reasons": sorted({w.failed[-1] for w in c.windows if w.attempt == "witness" and w.failed}),
                "refined_windows": int(sum(w.refined for w in c.windows)),
                # the NLP backend's errors where it raised (those windows kept their QP's durations or a point of it)
                "refinement_errors": sorted({w.refine_error for w in c.windows if w.refine_error}),
                # attempts the QP backend did not solve (not infeasible: failed, e.g. inaccurate at its iteration cap):
                # such windows fly a slower attempt; SCS flew the arena 1.54 x against 1.34 without a word (a tour)
                "solve_failures": _solve_failures(c.windows),
                "bisected_windows": int(sum(w.bisected > 0 for w in c.windows)),
                # the factor of the windows' durations the whole flight was re-timed to (a short flight), or null
                "retimed": c.retimed,
                "sampled_check": None if c.sampled is None else {
                    "rate_hz": sm.check_rate_hz, "min_separation_m": c.sampled.min_separation,
                    "min_clearance_m": _num(c.sampled.min_clearance), "in_obstacle": c.sampled.in_obstacle},
            })
        f = self.flight
        out["simulation"] = None if f is None else {
            "vehicle": self.config.simulation.vehicle,
            "backend": f.backend,  # the one that flew: simulation.backend = "auto" picks batched or processes
            "rate_hz": self.config.simulation.rate_hz,
            "max_tracking_error_m": f.max_tracking_error,
            "tracking_error_bound_m": f.tracking_bound,
            "rms_tracking_error_m": f.rms_tracking_error,
            **f.per_axis(),  # max_tracking_error_axis_m, rms_tracking_error_axis_m: {"x", "y", "z"}
            "min_separation_m": _num(f.min_separation),
            "min_obstacle_clearance_m": _num(f.min_clearance),
            "entered_obstacle": f.in_obstacle,
            # what the bound guarantees of the flown swarm: the planned margins minus the lag
            "guaranteed_clearance_m": None if f.tracking_bound is None
            else self.config.scenario.robot_radius - f.tracking_bound,
            "guaranteed_separation_m": None if f.tracking_bound is None
            else 2 * self.config.scenario.robot_radius - 2 * f.tracking_bound,
        }
        out["flight_quality"] = self.flight_quality()
        out["crazyflie"] = self.crazyflie_memory()
        out["config"] = self.config.to_dict()
        out["version"] = code_version()
        return out


def _solve_failures(windows: list) -> dict:
    """``{"windows": how many windows had an attempt the QP backend failed to solve, "statuses": its distinct
    statuses}`` (attempts it proved infeasible are not failures: a faster attempt often is). A status is the backend's
    own text, as ``SolverError.status`` holds it (the attempt's message quotes it: ``'MaxTime'``)."""
    statuses = {str(s) for w in windows for s in w.unsolved}
    return {"windows": sum(bool(w.unsolved) for w in windows), "statuses": sorted(statuses)}


@functools.cache
def code_version() -> dict:
    """``{"mrfswarm": the package's version, "commit": the git commit it runs from (with "+dirty" when files differ
    from it), or None outside a git checkout}``: ``result.json`` says which code made it, since defaults change
    between commits (a tour's runs straddled one, and their files could not tell; unset keys are null in the config).
    """
    import subprocess

    from mrfswarm import __version__

    root = Path(__file__).resolve().parent.parent
    commit = None
    if (root / ".git").exists():
        try:
            def git(*args: str) -> str:
                return subprocess.run(["git", "-C", str(root), *args], capture_output=True, text=True, timeout=10,
                                      check=True).stdout.strip()

            commit = git("rev-parse", "HEAD") + ("+dirty" if git("status", "--porcelain", "--untracked-files=no")
                                                 else "")
        except (OSError, subprocess.SubprocessError):
            commit = None
    return {"mrfswarm": __version__, "commit": commit}


def _num(v: float | None) -> float | None:
    return None if v is None or not np.isfinite(v) else float(v)


def resolve_config(config: Config | str | Path, *, mrf: str | None = None, qp: str | None = None,
                   nlp: str | None = None) -> Config:
    """A config object from a config or a path, with ``--mrf``/``--qp``/``--nlp`` applied and checked.

    ``mrf``, ``qp`` and ``nlp`` are shorthands: ``mrf=NAME`` sets ``mrf.method``,
    ``qp=NAME`` sets ``smoothing.backend`` and ``nlp=NAME`` ``smoothing.nlp`` (and
    ``smoothing.refinement = "nlp"``: naming a backend asks for it), over what the config gives.

    Raises
    ------
    SolverNotFound
        An unknown or missing MRF method (``mrf.method`` or ``mrf.escalation``), an unknown QP backend (whatever
        stage is on), a QP backend that is not installed where the continuous stage runs, or an NLP backend that
        the time refinement would use and that is not installed; the message begins with the config key.
    ConfigError
        A QP backend that cannot solve the continuous stage's problems (its capabilities
        lack inequality rows: regions, corridors and limits are inequalities), an ``nlp``
        that names no NLP backend, or an unknown ``simulation.vehicle`` (whatever stage is on).
    """
    # a Config changed in code (cfg.replace with dataclasses.replace) was not checked: a negative v_max ended in
    # "math domain error" inside the continuous stage, seam = "bogus" planned without a word
    cfg = validated(config) if isinstance(config, Config) else load_config(config)
    if mrf is not None:
        cfg = cfg.replace(mrf=dataclasses.replace(cfg.mrf, method=mrf))
    if qp is not None:
        cfg = cfg.replace(smoothing=dataclasses.replace(cfg.smoothing, backend=qp))
        # as an unused --nlp is said (a tour's --qp went unused without a word); an unknown name is refused below
        if not cfg.smoothing.enabled and qp in solvers.qp.BACKENDS:
            warnings.warn(f"QP backend {qp!r} not used: the continuous stage is off", UnusedSettingWarning,
                          stacklevel=2)
    if nlp is not None:  # naming an NLP backend asks for the NLP refinement
        check_nlp(nlp)  # the config's own check of the key
        cfg = cfg.replace(smoothing=dataclasses.replace(cfg.smoothing, nlp=nlp, refinement="nlp"))
        if not (cfg.smoothing.enabled and cfg.smoothing.time_refinement):
            warnings.warn(f"NLP backend {nlp!r} not used: smoothing.time_refinement is off "
                          "(--set smoothing.time_refinement=true)" if cfg.smoothing.enabled else
                          f"NLP backend {nlp!r} not used: the continuous stage is off", UnusedSettingWarning,
                          stacklevel=2)
    elif cfg.smoothing.enabled and cfg.smoothing.refinement != "nlp":
        default = next(f.default for f in dataclasses.fields(cfg.smoothing) if f.name == "nlp")
        if cfg.smoothing.nlp != default:  # set, and unused: the refinement is the scaling
            warnings.warn(f"smoothing.nlp = {cfg.smoothing.nlp!r} not used: smoothing.refinement is "
                          f"{cfg.smoothing.refinement!r} (set smoothing.refinement = \"nlp\" too, or give "
                          f"--nlp {cfg.smoothing.nlp})", UnusedSettingWarning, stacklevel=2)
    sm = cfg.smoothing
    if sm.nlp_options and not (sm.enabled and sm.time_refinement and sm.refinement == "nlp"):
        warnings.warn(f"smoothing.nlp_options = {sm.nlp_options} not used: they set the time refinement's NLP "
                      "backend, which runs with smoothing.time_refinement = true and smoothing.refinement = \"nlp\" "
                      "(--nlp NAME)", UnusedSettingWarning, stacklevel=2)
    _backend(mrf_solvers.METHODS, cfg.mrf.method, "mrf.method")  # fail now, not after the map is loaded
    if cfg.mrf.escalation != "none":  # a method that is not installed failed only at the first step it solved
        _backend(mrf_solvers.METHODS, cfg.mrf.escalation, "mrf.escalation")
    if cfg.smoothing.backend not in solvers.qp.BACKENDS:  # a name no backend has is wrong with the stage off too
        _backend(solvers.qp.BACKENDS, cfg.smoothing.backend, "smoothing.backend")
    from mrfswarm.simulation import check_available, check_vehicle

    check_vehicle(cfg.simulation.vehicle)
    if cfg.smoothing.enabled:
        record = _backend(solvers.qp.BACKENDS, cfg.smoothing.backend, "smoothing.backend")  # a missing one fails now
        if not record.capabilities.inequalities:
            able = ", ".join(solvers.qp.BACKENDS.available(lambda c: c.inequalities)) or "none"
            raise ConfigError(f"smoothing.backend = {record.name!r} solves equality-constrained problems only; the "
                              f"continuous stage's regions, corridors and limits are inequalities (installed "
                              f"backends that take them: {able})")
        if cfg.smoothing.time_refinement and cfg.smoothing.refinement == "nlp":
            _backend(solvers.nlp.BACKENDS, cfg.smoothing.nlp, "smoothing.nlp")  # registered, not installed
        if cfg.simulation.enabled:
            check_available(cfg.simulation.vehicle, cfg.simulation.backend)
    return cfg


def _backend(registry: Registry[C], name: str, key: str) -> Backend[C]:
    """``registry.get(name)``, its :class:`SolverNotFound` naming the config ``key`` that gave the name (``--mrf``,
    ``--qp`` and ``--nlp`` set one): "smoothing.backend: unknown QP backend 'nope'; installed: ...", as an unknown
    ``smoothing.nlp`` is said."""
    try:
        return registry.get(name)
    except SolverNotFound as e:
        raise SolverNotFound(f"{key}: {e}") from e


def with_seed(cfg: Config, seed: int | None) -> Config:
    """``cfg`` with ``seed`` (``--seed``) written where it acts: the sampled start's seed (a start given by
    positions has none) and ``mrf.options.seed``; so the config a result records plans the same again."""
    if seed is None:
        return cfg
    start = dict(cfg.scenario.start)
    if "positions" not in start:
        start["seed"] = seed
    return cfg.replace(scenario=dataclasses.replace(cfg.scenario, start=start),
                       mrf=dataclasses.replace(cfg.mrf, options={**cfg.mrf.options, "seed": seed}))


def mrf_options(cfg: Config, seed: int | None = None) -> mrf_solvers.Options:
    """The MRF method's options: the config's ``[mrf.options]`` over the defaults, ``seed`` (if given) over those."""
    options = mrf_solvers.Options(**cfg.mrf.options)
    return options if seed is None else dataclasses.replace(options, seed=seed)


def qp_options(cfg: Config) -> solvers.qp.Options:
    """The continuous stage's QP options: the config's ``[smoothing.qp_options]`` over the stage's own."""
    from mrfswarm.continuous.receding_horizon import QP_OPTIONS

    return dataclasses.replace(QP_OPTIONS, **cfg.smoothing.qp_options)


def plan(config: Config | str | Path, *, mrf: str | None = None, qp: str | None = None, nlp: str | None = None,
         seed: int | None = None, progress: bool | None = None, workers: int | None = None) -> Result:
    """Plan a scenario: the discrete stage, waypoint pruning, metrics, the continuous stage (``smoothing.enabled``)
    and the flight simulation (``simulation.enabled``).

    Parameters
    ----------
    config
        A :class:`Config` or a path to a TOML config (None: the default config).
    mrf, qp, nlp
        Shorthands for the config keys ``mrf.method`` (the MRF method, a name of
        ``solvers.mrf.METHODS``), ``smoothing.backend`` (the QP backend, a name of
        ``solvers.qp.BACKENDS``) and ``smoothing.nlp`` (the time refinement's NLP
        backend, a name of ``solvers.nlp.BACKENDS``): given, they replace the config's
        value, as ``--mrf NAME``, ``--qp NAME`` and ``--nlp NAME`` stand for ``--set
        mrf.method=NAME``, ``--set smoothing.backend=NAME`` and ``--set smoothing.nlp=NAME``
        (``nlp`` also sets ``smoothing.refinement = "nlp"``).
    seed
        Overrides the start sampling seed and the MRF method's (``mrf.options.seed``), an
        integer >= 0.
    progress
        Show a progress bar (default: when stderr is a terminal).
    workers
        Processes for the continuous stage's independent chunks of robots and for the
        simulation (default: the machine's cores). Plans do not depend on it.

    Raises
    ------
    ConfigError
        A bad config, seed or workers (the message names it).
    SolverNotFound
        An unknown or missing MRF method or QP backend, or a missing NLP backend with
        ``smoothing.time_refinement``.
    ScenarioError
        A scenario that cannot be planned (before the discrete stage).
    PlanError
        Any error after the discrete stage (a swarm that cannot move, a continuous
        stage or a simulation that fails); its ``result`` holds what was computed.

    Warns
    -----
    PlanWarning
        One per line of :meth:`Result.warnings` of a plan that completed, pointing at the
        caller: robots short of the goal or cut at ``mrf.max_steps``, windows flown as their
        rest-to-rest witness (slower, with stops), a QP backend that failed attempts of many
        windows, the NLP refinement's errors, a flight too long for a Crazyflie's memory, a
        simulated flight that came closer than the plan. ``mrfswarm run`` prints the same
        lines (``warnings.filterwarnings("ignore", category=PlanWarning)`` silences them).
    UnusedSettingWarning
        A setting the run does not use (``nlp`` without the time refinement).
    """
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, numbers.Integral) or seed < 0):
        raise ConfigError(f"seed = {seed!r}: must be an integer >= 0")
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, numbers.Integral) or workers < 1):
        raise ConfigError(f"workers = {workers!r}: must be a whole number >= 1")
    # a NumPy integer as a Python one: in the config it reached result.json, which json could not write
    seed, workers = (None if v is None else int(v) for v in (seed, workers))
    # a backend's warnings are said once per run ("reduced accuracy"), not once per process: a sweep's worker plans
    # several points, and said nothing of the second point's
    solvers.qp.base.forget_warned()
    cfg = with_seed(resolve_config(config, mrf=mrf, qp=qp, nlp=nlp), seed)
    timings: dict[str, float] = {}
    t0 = time.perf_counter()
    scn = build_scenario(cfg)
    timings["scenario"] = time.perf_counter() - t0
    _unused_scenario_settings(cfg, scn.grid.ndim)
    options = mrf_options(cfg)
    show = sys.stderr.isatty() if progress is None else progress
    from tqdm import tqdm

    with tqdm(total=cfg.mrf.max_steps, desc="MRF steps", unit="step", disable=not show, leave=False) as bar:
        t0 = time.perf_counter()
        problem = scn.discrete_problem()
        plan_d = plan_discrete(problem, method=cfg.mrf.method, max_steps=cfg.mrf.max_steps,
                               tol=cfg.mrf.tol, patience=cfg.mrf.patience, options=options,
                               on_step=lambda t, out: _discrete_progress(bar, t, cfg.mrf.max_steps),
                               progress=cfg.mrf.progress,
                               arrival=cfg.mrf.arrival)
        timings["discrete"] = time.perf_counter() - t0
    metrics = _discrete_metrics(cfg, scn, problem, plan_d)
    alternatives, plan_d.alternatives = plan_d.alternatives, ()  # compared by flying (_continuous), and only there
    result = Result(config=cfg, scenario=scn, discrete=plan_d, metrics=metrics, pruned=[], timings_s=timings)
    try:
        if plan_d.n_steps == 0 and plan_d.stop_reason != "arrived" and metrics.reached_goal is False:
            raise ScenarioError(
                f"the swarm cannot move: {cfg.mrf.method} found no move from the start that lowers the swarm energy "
                f"(goal {metrics.final_goal_distance:.1f} m away)")  # what the method found (BP said none where ICM moved)
        if cfg.smoothing.enabled:
            _continuous(result, show, workers, problem, alternatives)
        if cfg.smoothing.enabled and cfg.simulation.enabled:
            _simulate(result, show, workers)
    except SolversError as e:
        result.failure = str(e)
        _paper_pruning(result)
        raise PlanError(str(e), result) from e  # the CLI still writes what was computed
    _paper_pruning(result)
    # what `mrfswarm run` prints after its summary line: a caller in Python heard none of it (every window flown as
    # its rest-to-rest witness under smoothing.qp_options.max_iter = 1, free5 flying 13.3 s instead of 4.7, unsaid)
    for text in result.warnings():
        warnings.warn(text, PlanWarning, stacklevel=2)
    return result


def _discrete_metrics(cfg: Config, scn: Scenario, problem: DiscreteProblem, plan_d: DiscretePlan) -> DiscreteMetrics:
    # the arrival rule also ends a plan whose other robots are cut off from the goal: those did not reach it
    cut_off = problem.goal_path is not None and not np.isfinite(cell_values(problem.goal_path, plan_d.paths[-1])).all()
    return discrete_metrics(plan_d.paths, scn.grid.occupied, scn.grid.resolution, scn.goal, scn.goal_radius,
                            downwash=cfg.scenario.downwash, arrived=plan_d.stop_reason == "arrived" and not cut_off)


def _unused_scenario_settings(cfg: Config, dim: int) -> None:
    """Say (:class:`UnusedSettingWarning`) a scenario setting the map's dimension leaves unused: ``altitude`` on a
    3-D map (the robots' z is the map's), ``downwash`` on a 2-D one (every robot flies at one altitude). Both were
    accepted without a word (a 3-D tour); a value equal to the default cannot be told from an unset one."""
    s, default = cfg.scenario, type(cfg.scenario)()
    if dim == 3 and s.altitude != default.altitude:
        warnings.warn(f"scenario.altitude = {s.altitude:g} not used: on a 3-D map the robots' z comes from the map's "
                      "frame", UnusedSettingWarning, stacklevel=3)
    if dim == 2 and s.downwash != default.downwash:
        warnings.warn(f"scenario.downwash = {s.downwash:g} not used: on a 2-D map every robot flies at one altitude",
                      UnusedSettingWarning, stacklevel=3)


def _discrete_progress(bar, t: int, max_steps: int) -> None:
    """The progress bar, and with ``-v`` a line every 50 MRF steps (a long run without a terminal has no bar)."""
    bar.update(t - bar.n)
    if t % 50 == 0:
        log.info("discrete stage: MRF step %d (at most %d)", t, max_steps)


def _paper_pruning(result: Result) -> None:
    """Without a receding horizon's pruning, the paper's: per planning horizon."""
    if not result.pruned:
        t0 = time.perf_counter()
        result.pruned = prune_paths(result.discrete.paths, result.scenario.grid.free, result.config.smoothing.horizon)
        result.timings_s["pruning"] = time.perf_counter() - t0


def _continuous(result: Result, show: bool, workers: int | None, problem: DiscreteProblem,
                alternatives: tuple[DiscretePlan, ...] = ()) -> None:
    """Smooth ``result.discrete``; where its flight is short enough to be re-timed as a whole
    (:attr:`~mrfswarm.continuous.RecedingHorizon.retimes`), fly each of ``alternatives`` too (the other plans of
    ``mrf.contested = "auto"``, :attr:`~mrfswarm.discrete.planner.DiscretePlan.alternatives`) and keep the one flown
    soonest, with its discrete plan and metrics.

    The flight model ``"auto"`` picks by does not know the re-timing: on the arena (8 robots, 16 steps) it put the
    "downhill" plan 3 % sooner than the "shared" one, which flew 5 % sooner (5.43 s against 5.71). A short flight
    costs little to smooth (the arena about 1 s), so it is flown rather than modelled."""
    from tqdm import tqdm

    from mrfswarm.continuous import RecedingHorizon

    cfg = result.config
    plans = [result.discrete, *alternatives]

    def horizon(d: DiscretePlan) -> RecedingHorizon:
        return RecedingHorizon(d.paths, result.scenario.grid, cfg.smoothing, cfg.scenario.robot_radius,
                               cfg.smoothing.backend, qp_options(cfg), workers=workers, downwash=cfg.scenario.downwash)

    pairs = [(plans[0], horizon(plans[0]))]  # (discrete plan, its smoothing) of every plan flown
    if len(plans) > 1 and pairs[0][1].retimes:
        for d in plans[1:]:
            try:
                rh = horizon(d)
            except SolversError as e:  # the kept plan's failure is the run's; another's only leaves it out
                log.info("smoothing: the plan of contested = %r not flown: %s", d.contested, e)
                continue
            if rh.retimes:
                pairs.append((d, rh))
    windows = sum(len(rh.windows()) for _, rh in pairs)
    log.info("continuous stage: %d robots, %d steps in %d windows", result.scenario.n_robots,
             result.discrete.n_steps, len(pairs[0][1].windows()))
    done = [0]
    t0 = time.perf_counter()

    def on_window(w) -> None:
        done[0] += 1
        bar.update(1)
        # -v on a long run without a terminal (no progress bar): a line at every tenth of the windows
        if done[0] * 10 // windows > (done[0] - 1) * 10 // windows:
            log.info("smoothing: window %d of %d (steps %d..%d) after %.1f s", done[0], windows, w.a, w.b,
                     time.perf_counter() - t0)

    flown: list[tuple[float, int, ContinuousPlan]] = []
    error: SolversError | None = None
    with tqdm(total=windows, desc="smoothing", unit="window", disable=not show, leave=False) as bar:
        for k, (d, rh) in enumerate(pairs):
            try:
                c = rh.run(on_window=on_window)
            except SolversError as e:
                if len(pairs) == 1:
                    raise
                log.info("smoothing: the plan of contested = %r not flown: %s", d.contested, e)
                error = error or e  # the model's pick's error first
                continue
            flown.append((c.makespan_s, k, c))
    if not flown:
        assert error is not None
        raise error
    _, k, plan = min(flown, key=lambda f: f[:2])
    if len(pairs) > 1:
        log.info("contested = \"auto\": the short flights of its plans flown (the flight model does not know their "
                 "re-timing): %s; kept %r", ", ".join(f"{pairs[j][0].contested!r} {s:.2f} s" for s, j, _ in flown),
                 pairs[k][0].contested)
    if k:
        result.discrete = pairs[k][0]
        result.metrics = _discrete_metrics(cfg, result.scenario, problem, pairs[k][0])
    result.continuous = plan
    result.timings_s.update(plan.timings)
    if len(pairs) > 1:  # the other flights' planning is the run's too
        result.timings_s["smoothing_alternatives"] = sum(sum(c.timings.values()) for _, j, c in flown if j != k)


#: Robot-seconds of flight (at 100 Hz) above which the per-process simulation is said to take long: it flew 20 robots'
#: 30 s in 74 s on 2 processes (0.25 s per robot-second in each), so this is about two minutes there. A tour ran
#: swarm100.toml as shipped and waited minutes with nothing said (the simulation is on by default).
LONG_SIMULATION = 1000.0


def _say_long_simulation(robots: int, seconds: float, rate_hz: float, backend: str) -> None:
    from mrfswarm.simulation import resolve_backend

    work = robots * seconds * rate_hz / 100.0
    if work > LONG_SIMULATION and resolve_backend(backend) == "processes":
        log.warning("simulating %d robots for %.0f s of flight each at %g Hz, one robot at a time per process: this "
                    "takes minutes (simulation.enabled = false skips it; simulation.backend = \"batched\", with "
                    "mrfswarm[batched], flies them together)", robots, seconds, rate_hz)


def _simulate(result: Result, show: bool, workers: int | None = None) -> None:
    from mrfswarm.simulation import fly_swarm

    cfg = result.config
    t0 = time.perf_counter()
    c = result.smoothed()
    log.info("simulation: %d robots, %.1f s of flight at %g Hz (simulation.backend = %r)", len(c.trajectories),
             c.makespan_s, cfg.simulation.rate_hz, cfg.simulation.backend)
    _say_long_simulation(len(c.trajectories), c.makespan_s, cfg.simulation.rate_hz, cfg.simulation.backend)
    result.flight = fly_swarm(c.trajectories, cfg.scenario.altitude, result.scenario.grid,
                              cfg.simulation.rate_hz, cfg.simulation.vehicle, jerk=c.j_max,
                              workers=workers, speed=c.v_max, progress=show,
                              backend=cfg.simulation.backend, downwash=cfg.scenario.downwash)
    result.timings_s["simulation"] = time.perf_counter() - t0
