"""``plan``: a scenario config in, discrete paths (and later trajectories) and metrics out."""

from __future__ import annotations

import dataclasses
import logging
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mrfswarm.config import Config, load_config
from mrfswarm.discrete import DiscretePlan, plan_discrete
from mrfswarm.metrics import DiscreteMetrics, discrete_metrics
from mrfswarm.pruning import prune_paths
from mrfswarm.scenario import Scenario, build_scenario
from solvers import mrf as mrf_solvers

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
        Per robot, step indices kept by waypoint pruning (per planning horizon).
    timings_s
        Seconds per pipeline stage.
    """

    config: Config
    scenario: Scenario
    discrete: DiscretePlan
    metrics: DiscreteMetrics
    pruned: list[np.ndarray]
    timings_s: dict[str, float] = field(default_factory=dict)

    @property
    def mrf(self) -> str:
        return self.config.mrf.optimizer

    @property
    def qp(self) -> str | None:
        return self.config.smoothing.backend if self.config.smoothing.enabled else None

    def discrete_paths_world(self) -> np.ndarray:
        """(T + 1, N, 2) discrete paths in metres."""
        return self.scenario.grid.cell_to_world(self.discrete.paths)

    def summary(self) -> dict:
        """The content of ``result.json``."""
        m = self.metrics
        g = self.scenario.goal_world
        return {
            "n_robots": self.scenario.n_robots,
            "mrf_steps": self.discrete.n_steps,
            "converged": self.discrete.converged,
            "reached_goal": m.reached_goal,
            "goal": None if g is None else [float(v) for v in g],
            "final_goal_distance": m.final_goal_distance,
            "swarm_energy": [float(e) for e in self.discrete.energy],
            "min_separation_discrete": _num(m.min_separation),
            "min_separation_continuous": None,
            "min_obstacle_clearance": _num(m.min_obstacle_clearance),
            "mean_inter_robot_distance_final": _num(m.mean_distance[-1]),
            "path_lengths": [float(v) for v in m.path_lengths],
            "makespan_s": None,
            "mrf": self.mrf,
            "qp": self.qp,
            "mrf_order": self.config.mrf.order,
            "k": self.config.interaction.k,
            "pruned_waypoints": [int(len(p)) for p in self.pruned],
            "mrf_step_time_s": {k: float(np.mean(v)) if len(v) else 0.0 for k, v in self.discrete.timings.items()},
            "mrf_repaired": int(sum(s["repaired"] for s in self.discrete.steps)),
            "timings_s": {k: float(v) for k, v in self.timings_s.items()},
            "config": self.config.to_dict(),
        }


def _num(v: float | None) -> float | None:
    return None if v is None or not np.isfinite(v) else float(v)


def resolve_config(config: Config | str | Path, *, mrf: str | None = None, qp: str | None = None) -> Config:
    """A config object from a config or a path, with ``--mrf``/``--qp`` applied and checked.

    Raises
    ------
    SolverNotFound
        An unknown or missing MRF method.
    """
    cfg = config if isinstance(config, Config) else load_config(config)
    if mrf is not None:
        cfg = cfg.replace(mrf=dataclasses.replace(cfg.mrf, optimizer=mrf))
    if qp is not None:
        cfg = cfg.replace(smoothing=dataclasses.replace(cfg.smoothing, backend=qp))
    mrf_solvers.METHODS.get(cfg.mrf.optimizer)  # fail now, not after the map is loaded
    return cfg


def plan(config: Config | str | Path, *, mrf: str | None = None, qp: str | None = None, seed: int | None = None,
         progress: bool | None = None) -> Result:
    """Plan a scenario: the discrete stage, waypoint pruning, metrics.

    Parameters
    ----------
    config
        A :class:`Config` or a path to a TOML config.
    mrf, qp
        Override the MRF optimizer / QP backend.
    seed
        Overrides the start sampling seed and the optimizer's seed.
    progress
        Show a progress bar (default: when stderr is a terminal).
    """
    cfg = resolve_config(config, mrf=mrf, qp=qp)
    timings: dict[str, float] = {}
    t0 = time.perf_counter()
    scn = build_scenario(cfg, seed)
    timings["scenario"] = time.perf_counter() - t0
    options = mrf_solvers.Options(seed=0 if seed is None else seed)
    show = sys.stderr.isatty() if progress is None else progress
    from tqdm import tqdm

    with tqdm(total=cfg.mrf.max_steps, desc="MRF steps", unit="step", disable=not show, leave=False) as bar:
        t0 = time.perf_counter()
        plan_d = plan_discrete(scn.discrete_problem(), method=cfg.mrf.optimizer, max_steps=cfg.mrf.max_steps,
                               tol=cfg.mrf.tol, options=options, on_step=lambda t, out: bar.update(1))
        timings["discrete"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    pruned = prune_paths(plan_d.paths, scn.grid.free, cfg.smoothing.horizon)
    timings["pruning"] = time.perf_counter() - t0
    metrics = discrete_metrics(plan_d.paths, scn.grid.occupied, scn.grid.resolution, scn.goal,
                               cfg.scenario.goal_radius)
    return Result(config=cfg, scenario=scn, discrete=plan_d, metrics=metrics, pruned=pruned, timings_s=timings)
