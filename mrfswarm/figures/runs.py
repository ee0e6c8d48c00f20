"""The planner runs behind the paper figures, computed once per process.

Every figure that shows a scenario of Section V reads it from :func:`scenario_run`, so the
trajectories of Fig. 6, the robot positions of Fig. 7a, the corridor distances of
Fig. 7c and the energies of Fig. 8a come from the same four runs. Runs are cached by
their arguments (a figure run and the tests in one process plan each scenario once).
The quadrotor simulation is switched off: no paper figure shows it, and it is the
slowest stage by far.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

from mrfswarm.config import Config, load_config
from mrfswarm.errors import ConfigError
from mrfswarm.pipeline import Result, plan

#: The experiment configs (the repository's ``experiments/`` folder).
EXPERIMENTS = Path(__file__).resolve().parents[2] / "experiments"

#: The four scenarios of the paper's Figs. 6 and 8a, in the paper's panel order.
SCENARIOS = ("free5", "free10", "corridor", "blocks")

#: How the continuous stage is run:
#: ``discrete``: no smoothing; ``single``: one min-snap window over the whole discrete
#: path (Fig. 6e, f: "optimized trajectories"); ``paper``: the paper's receding horizon
#: (4 steps planned, 50 % executed, rest at the seams); ``default``: ours (safe regions,
#: 8 steps planned, 50 % executed, continuous up to jerk at the seams; Fig. 6g, h);
#: ``refined``: ours with the step durations refined (the default refinement, the multiplier scaling).
SMOOTHING: dict[str, tuple[str, ...]] = {
    "discrete": ("smoothing.enabled=false",),
    "single": ("smoothing.horizon=100000", "smoothing.execution=1.0"),
    "paper": ('smoothing.seam="rest"', "smoothing.horizon=4", "smoothing.execution=0.5"),
    "default": (),
    "refined": ("smoothing.time_refinement=true",),
}


def experiment_config(name: str, overrides: tuple[str, ...] = ()) -> Config:
    """``experiments/<name>.toml`` with the simulation off and ``overrides`` (``--set`` syntax) applied.

    Raises
    ------
    ConfigError
        No such experiment config.
    """
    path = EXPERIMENTS / f"{name}.toml"
    if not path.is_file():
        raise ConfigError(f"no experiment config {name!r} (looked for {path})")
    return load_config(path, ["simulation.enabled=false", *overrides])


@lru_cache(maxsize=None)
def scenario_run(name: str, smoothing: str = "default", overrides: tuple[str, ...] = (), seed: int | None = None) -> Result:
    """Plan ``experiments/<name>.toml`` (cached).

    Parameters
    ----------
    name
        Experiment config name.
    smoothing
        A key of :data:`SMOOTHING`.
    overrides
        Extra ``KEY=VALUE`` config overrides.
    seed
        Start-sampling and optimizer seed (None: the config's).
    """
    if smoothing not in SMOOTHING:
        raise ConfigError(f"smoothing mode {smoothing!r}; allowed: {', '.join(SMOOTHING)}")
    cfg = experiment_config(name, (*SMOOTHING[smoothing], *overrides))
    return plan(cfg, seed=seed, progress=False)


def discrete_run(name: str, overrides: tuple[str, ...] = (), seed: int | None = None) -> Result:
    """The discrete stage only of ``experiments/<name>.toml`` (cached)."""
    return scenario_run(name, "discrete", overrides, seed)
