"""The discrete stage: one MRF optimization per step until the swarm energy converges.

Each step t: build the interaction graph G_t on the robots' cells x^{t-1}, its maximal
cliques and their pairwise reduction; build the label sets X^t and the hard conflicts;
hand the step's pairwise MRF to an optimizer of :mod:`solvers.mrf` (ICM by default)
starting from "everybody stays"; move. Stop when a step lowers the swarm energy (on its
own graph) by less than ``tol`` (relative): *converged* if every robot that can reach the
goal region is in it (or there is no goal), *trapped* otherwise (ICM, a local method,
found no move that lowers the energy short of the goal). The k-NN graph changes as the
swarm moves, so the dynamics need not have a fixed point (a swarm packed at its goal
can keep circulating, each step lowering the energy of its own graph); such a run stops
as *stalled* when it has made no progress (a new minimum of the swarm energy, or of the
robots' static field sum: ``progress``) for ``patience`` steps, and its paths end at the
step of its last progress (the steps after it only circulate). Otherwise it stops at
``max_steps``. Every step also counts the robots separated from the swarm (nearest
neighbour beyond 1.5 d_min).

``energy[t]`` is the swarm energy of configuration x^t on its own interaction graph
G(x^t): the quantity the paper plots in its convergence figure.

Cells are (N, d), d = 2 or 3 (voxel grids), by the same lines. In 3-D every pair of
robots keeps at least one cell in the downwash-scaled metric (``downwash``; a hard
conflict of each step, checked on every plan); the interaction graph and the Morse
potential use the plain Euclidean distance: they shape the swarm, while the downwash is
a safety rule, which holds for all pairs, neighbours or not.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.spatial import cKDTree

from mrfswarm.config import PROGRESS_RULES
from mrfswarm.discrete.congestion import CongestionField
from mrfswarm.discrete.interaction_graph import CliqueWeights, clique_weights_of_graph, knn_edges, update_clique_weights
from mrfswarm.discrete.label_sets import LabelSets, label_sets
from mrfswarm.discrete.loops import drop_loops
from mrfswarm.discrete.merge_waits import FlightTime, merge_waits
from mrfswarm.discrete.motion import MIN_SEPARATION, cell_values, step_min_separation
from mrfswarm.discrete.potentials import Morse
from mrfswarm.discrete.safety import discrete_violations
from mrfswarm.discrete.step_mrf import step_mrf
from mrfswarm.discrete.straighten import straighten
from mrfswarm.errors import ScenarioError, SolversError
from mrfswarm.geometry import norm
from solvers import mrf as mrf_solvers
from solvers.mrf import PairwiseMRF

log = logging.getLogger(__name__)

#: The per-step stages whose times are recorded, in order.
STAGES = ("graph", "cliques", "labels", "energy", "optimizer")
#: The contested rules ``contested = "auto"`` plans with, in this order (:func:`plan_discrete`). "queue" since the
#: twenty-fifth session (flight_quality bench against b8824f7, picked by the fast profile's model, where it keeps
#: it): the funnel into one gap 30.23 -> 28.56 s (0.80 -> 0.50 stops per robot), aisles30 35.88 -> 35.10,
#: clutter40@7 52.95 -> 47.09, but clutter40 49.07 -> 49.65 and @4 49.06 -> 49.74 (the model's times are not the
#: flown ones); the seven clutter maps 348.9 -> 344.3 s in sum; big200 152.4 -> 150.0 s (0.95 -> 0.82 stops); the
#: discrete stage costs about 1.5 x where it is planned (:data:`QUEUE_WAITS`).
AUTO_RULES = ("downhill", "shared", "queue")
#: With ``"auto"``, a later rule's plan ends after this many times the first plan's steps: it would fly later.
AUTO_STEP_CAP = 1.1
#: With ``"auto"``, "queue" is planned only after a "shared" plan whose robots wait at least this many steps each
#: on average short of the goal region (:func:`waits_per_robot`): "queue" plans as "shared" until robots wait, and
#: a swarm that hardly waits has no queue to merge into. The 300-robot crossing waits 0.09 steps per robot (its
#: "queue" plan flew the same and cost 1.5 x the discrete stage), the open field 0.02, the forest 0.2; aisles30
#: 0.33 (flew 2 % sooner with "queue"), the clutter maps 1.5-2.4, the halls 4.2, the funnel 6.
QUEUE_WAITS = 0.25


#: A robot whose nearest neighbour is farther than this many d_min is separated from the swarm.
SEPARATION_FACTOR = 1.5


@dataclass(frozen=True)
class DiscreteProblem:
    """Everything the discrete stage needs, in grid cells.

    Attributes
    ----------
    free
        (W, H) or (W, H, D) bool, True where free.
    static
        The static field rho_S = rho_G + rho_O over the grid.
    start
        (N, d) distinct free start cells, d = ``free.ndim``.
    goal
        Goal cell (d,) or None (no goal potential).
    morse
        The interaction potential rho_D.
    resolution
        Metres per cell (potential distances are in metres).
    k, order
        Neighbours in the interaction graph; label-set order n.
    trim_backward, contested, follow
        Label-set rules (:func:`mrfswarm.discrete.label_sets.label_sets`).
    trim_escape
        With ``trim_backward``: a robot that has stayed in its cell for the last
        ``trim_escape`` steps is not trimmed (0: every robot always is).
    trim_slack
        With ``trim_backward`` and ``goal_distance``: a move that raises the goal distance
        by at most this many cells is kept (``mrf.trim_slack``).
    goal_distance
        The distance the goal field uses when it is not the straight line (the
        geodesic one); ``trim_backward`` then drops moves that increase it.
    goal_path
        Length (metres) of the shortest free path from each cell to the goal
        (``inf`` without one), or None: then any fixed point of the energy counts as
        converged.
    goal_region_radius
        A robot with ``goal_path <= goal_region_radius`` is at the goal. A run whose
        energy stops decreasing with a robot that could reach the goal region outside it
        ends as ``"trapped"``, not ``"converged"``.
    downwash
        c = ``scenario.downwash`` >= 1: robots keep one cell apart in the metric of
        :func:`mrfswarm.geometry.downwash_scale` (z / c in 3-D; no effect in 2-D).
    congestion
        Recomputes the goal field around stalled robots every few steps
        (:mod:`mrfswarm.discrete.congestion`); None keeps ``static`` throughout.
    merge_waits
        Merge each robot's waits between runs of moves once the paths are planned
        (:mod:`mrfswarm.discrete.merge_waits`).
    drop_loops
        Once the paths are planned (before the waits are merged), a robot that comes back
        to a cell waits there instead where safe (:mod:`mrfswarm.discrete.loops`).
    straighten
        Once the loops are dropped (before the waits are merged), each robot's way between two of
        its steps shortened where safe, no move longer (:mod:`mrfswarm.discrete.straighten`).
    flight
        The flight-time model a merge must not lengthen (None: every safe merge is made).
    pick
        The flight-time model ``contested = "auto"`` keeps the soonest plan by (None: ``flight``'s; see
        :func:`flight_time`).
    escalation
        The MRF method a step is solved again by when the plan's method leaves it without progress
        short of the goal (its solution taken if it moves robots to a lower energy); None: the plan
        ends there (the paper's).
    """

    free: np.ndarray
    static: np.ndarray
    start: np.ndarray
    goal: np.ndarray | None
    morse: Morse
    resolution: float = 1.0
    k: int = 3
    order: int = 2
    trim_backward: bool = False
    trim_escape: int = 0
    trim_slack: float = 0.0
    contested: str = "downhill"
    follow: bool = False
    goal_distance: np.ndarray | None = None
    goal_path: np.ndarray | None = None
    goal_region_radius: float = 0.0
    downwash: float = 1.0
    congestion: CongestionField | None = None
    merge_waits: bool = False
    drop_loops: bool = False
    straighten: bool = False
    flight: FlightTime | None = None
    escalation: str | None = None
    pick: FlightTime | None = None


@dataclass(frozen=True)
class StepOutcome:
    """One MRF step."""

    positions: np.ndarray
    energy_before: float
    energy_after: float
    result: mrf_solvers.MRFResult
    weights: CliqueWeights
    timings: dict[str, float]
    #: the step MRF the method solved (its label sets trimmed and its field congested as the step's were)
    model: mrf_solvers.PairwiseMRF

    @property
    def moved(self) -> int:
        return int(np.count_nonzero(self.result.labels))


@dataclass
class DiscretePlan:
    """The discrete paths and what the stage recorded.

    Attributes
    ----------
    paths
        (T + 1, N, d) cells, x^0 .. x^T: the MRF's configurations, with each robot's loops
        dropped when ``drop_loops`` is on and its waits merged when ``merge_waits`` is on.
    energy
        (T + 1,) swarm energy of each of the MRF's configurations on its own graph (and,
        with congestion, the goal field of its step).
    converged
        True if the energy converged (a step lowered it by less than the tolerance) with
        every robot that can reach the goal region in it (any fixed point without a goal).
    stop_reason
        "arrived" (every robot that can reach the goal region is in it, ``mrf.arrival``; counted as
        converged); "converged"; "trapped" (the energy stopped decreasing with robots short of the
        goal region: ICM, a local method, found no move that lowers it); "stalled" (no
        progress in ``patience`` steps; the paths end at the last progress) or
        "max_steps".
    timings
        stage -> (T,) seconds per step.
    steps
        Per-step optimizer facts: iterations, repaired, lower bound, moved robots.
    merged_waits
        Waits moved by :func:`~mrfswarm.discrete.merge_waits.merge_waits` (0 when off).
    dropped_loops
        Loops replaced by waits by :func:`~mrfswarm.discrete.loops.drop_loops` (0 when off).
    straightened
        Windows shortened by :func:`~mrfswarm.discrete.straighten.straighten` (0 when off).
    congested_fields
        Goal fields recomputed around stalled robots (:mod:`mrfswarm.discrete.congestion`).
    escalated
        Steps solved by ``problem.escalation`` after the plan's method left them without progress.
    contested
        The contested rule the plan was made with (the one ``"auto"`` picked).
    alternatives
        With ``contested = "auto"``: the rules' other plans that leave as few robots short of the goal region and
        as little way as this one (its paths differ), sooner by :func:`flight_time` first. The pipeline flies them
        too where a flight is short enough to be re-timed as a whole, which the flight model does not know
        (:func:`mrfswarm.pipeline.plan`), and keeps the one flown soonest.
    """

    paths: np.ndarray
    energy: np.ndarray
    converged: bool
    timings: dict[str, np.ndarray]
    steps: list[dict] = field(default_factory=list)
    stop_reason: str = "max_steps"
    merged_waits: int = 0
    dropped_loops: int = 0
    straightened: int = 0
    congested_fields: int = 0
    contested: str = ""
    escalated: int = 0
    alternatives: tuple[DiscretePlan, ...] = ()

    @property
    def n_steps(self) -> int:
        return len(self.paths) - 1


def graph_weights(positions: np.ndarray, k: int, timings: dict[str, float] | None = None,
                  previous: CliqueWeights | None = None) -> CliqueWeights:
    """G(x): k-NN edges, maximal cliques and their counts, timed into ``timings``.

    ``previous``: the graph of the step before, whose cliques away from the robots that
    changed neighbours are kept (:func:`~mrfswarm.discrete.interaction_graph.update_clique_weights`).
    """
    t0 = time.perf_counter()
    edges = knn_edges(positions.astype(float), k)
    t1 = time.perf_counter()
    if previous is None:
        w = clique_weights_of_graph(len(positions), edges)
    else:
        w = update_clique_weights(previous, len(positions), edges)
    t2 = time.perf_counter()
    if timings is not None:
        timings["graph"] = t1 - t0
        timings["cliques"] = t2 - t1
    return w


def mrf_step(problem: DiscreteProblem, positions: np.ndarray, method: str = "icm",
             options: mrf_solvers.Options | None = None, weights: CliqueWeights | None = None,
             graph_timings: dict[str, float] | None = None, trim: np.ndarray | None = None,
             waited: np.ndarray | None = None) -> StepOutcome:
    """Run one MRF step from ``positions`` (N, d) cells.

    ``weights`` (with the ``graph_timings`` it took) may be passed when G(positions) is
    already known; ``trim`` (N,) bool, which robots ``trim_backward`` applies to (None: all);
    ``waited`` (N,), the steps each robot has stayed in its cell, which ``contested = "queue"``
    visits first (None: nobody has waited).
    """
    timings: dict[str, float] = {}
    if weights is None:
        weights = graph_weights(positions, problem.k, timings)
    else:
        timings.update(graph_timings or {"graph": 0.0, "cliques": 0.0})
    labels, model = step_model(problem, positions, weights, timings, trim, waited)
    t0 = time.perf_counter()
    res = mrf_solvers.minimize(model, method=method, options=options)
    timings["optimizer"] = time.perf_counter() - t0
    new = positions + labels.offsets[np.arange(len(positions)), res.labels]
    return StepOutcome(
        positions=new,
        energy_before=model.energy(model.initial),
        energy_after=res.energy,
        result=res,
        weights=weights,
        timings=timings,
        model=model,
    )


def step_model(problem: DiscreteProblem, positions: np.ndarray, weights: CliqueWeights,
               timings: dict[str, float] | None = None, trim: np.ndarray | None = None,
               waited: np.ndarray | None = None) -> tuple[LabelSets, PairwiseMRF]:
    """The MRF of one step from ``positions`` (N, d) cells on the graph ``weights`` = G(positions).

    The label sets X^t (:func:`problem_label_sets`) and the step's pairwise MRF over them
    (:func:`~mrfswarm.discrete.step_mrf.step_mrf`: unary and pairwise terms of the clique
    energies, hard conflicts, "everybody stays" as the initial labelling; with ``contested =
    "queue"`` the robots that have ``waited`` longest visited first). Their build times go into
    ``timings`` (``"labels"``, ``"energy"``) when it is given.
    """
    t0 = time.perf_counter()
    labels = problem_label_sets(problem, positions, trim)
    t1 = time.perf_counter()
    priority = None
    if problem.contested == "queue":
        priority = np.zeros(len(positions)) if waited is None else np.asarray(waited, dtype=float)
    model = step_mrf(labels, weights, problem.static, problem.morse, problem.resolution, problem.downwash,
                     priority)
    if timings is not None:
        timings["labels"] = t1 - t0
        timings["energy"] = time.perf_counter() - t1
    return labels, model


def problem_label_sets(problem: DiscreteProblem, positions: np.ndarray, trim: np.ndarray | None = None) -> LabelSets:
    """X^t for the robots at ``positions`` under the problem's label-set rules (``trim``: the robots
    ``trim_backward`` applies to, None: all)."""
    rule = problem.trim_backward if trim is None or not problem.trim_backward else trim
    contested = "shared" if problem.contested == "queue" else problem.contested  # its label sets are shared's
    return label_sets(problem.free, positions, problem.order, problem.goal, rule, problem.static,
                      contested, problem.goal_distance, problem.follow, problem.downwash,
                      problem.trim_slack * problem.resolution)


def trim_mask(problem: DiscreteProblem, paths: list[np.ndarray]) -> np.ndarray | None:
    """(N,) the robots ``trim_backward`` applies to in the next step: all but those that have stayed in their
    cell for the last ``trim_escape`` steps of ``paths`` (None: all)."""
    E = problem.trim_escape
    if not problem.trim_backward or E <= 0 or len(paths) <= E:
        return None
    last = np.stack(paths[-E - 1:])
    return ~np.all(np.all(last == last[-1], axis=-1), axis=0)


def _static_sum(problem: DiscreteProblem, positions: np.ndarray) -> float:
    return float(cell_values(problem.static, positions).sum())


def separation_cells(problem: DiscreteProblem) -> float:
    """Nearest-neighbour distance (cells) beyond which a robot is separated: 1.5 d_min."""
    return SEPARATION_FACTOR * problem.morse.d_min / problem.resolution


def nearest_neighbour_cells(positions: np.ndarray) -> np.ndarray:
    """(N,) distance (cells) from each robot to its nearest other robot (cKDTree)."""
    if len(positions) < 2:
        return np.full(len(positions), np.inf)
    d, _ = cKDTree(positions.astype(float)).query(positions.astype(float), 2)
    return d[:, 1]


def _check_start(problem: DiscreteProblem, start: np.ndarray) -> None:
    if start.ndim != 2 or start.shape[1] != problem.free.ndim:
        raise ScenarioError(f"start cells have shape {start.shape}, the grid has {problem.free.ndim} axes")
    cut = ~np.isfinite(cell_values(problem.static, start))
    if cut.any():
        i = int(np.flatnonzero(cut)[0])
        raise ScenarioError(f"robot {i} at cell {tuple(int(v) for v in start[i])} has no free path to the goal "
                            f"({int(cut.sum())} robot(s) cut off)")
    # staying must be feasible for everybody (every step starts from it): the start keeps
    # every pair one cell apart in the downwash-scaled metric
    d, pair = step_min_separation(start, start, problem.downwash)
    if d < MIN_SEPARATION - 1e-9 and pair is not None:
        i, j = pair
        raise ScenarioError(f"robots {i} and {j} start at cells {tuple(int(v) for v in start[i])} and "
                            f"{tuple(int(v) for v in start[j])}, {d:.3g} cells apart in the downwash-scaled metric "
                            f"(scenario.downwash = {problem.downwash:g}); they must be at least 1 apart")


def swarm_energy(problem: DiscreteProblem, positions: np.ndarray, weights: CliqueWeights | None = None) -> float:
    """eps(x) on the interaction graph of x (pairwise reduction)."""
    w = weights if weights is not None else graph_weights(positions, problem.k)
    cells = positions
    e = float((w.node * cell_values(problem.static, cells)).sum())
    if len(w.edges):
        d = norm(cells[w.edges[:, 0]] - cells[w.edges[:, 1]]) * problem.resolution
        e += float((w.edge * problem.morse(d)).sum())
    return e


class _Progress:
    """The patience rule: the steps since the last progress, and the step that made it.

    Progress is a new minimum (by more than ``tol``, relative above 1) of the swarm energy
    or, with ``rule = "static"``, of the robots' static field sum.
    """

    def __init__(self, tol: float, rule: str, static_sum: float) -> None:
        self.tol, self.rule = tol, rule
        self.best, self.best_static = np.inf, static_sum
        self.best_t, self.since = 0, 0

    def _lower(self, value: float, best: float) -> bool:
        return value < best - self.tol * max(1.0, abs(best))

    def record(self, t: int, energy: float, static_sum: float) -> None:
        """After step ``t``: the swarm energy and static field sum it reached."""
        improved = self._lower(energy, self.best)
        if improved:
            self.best = energy
        if self.rule == "static" and self._lower(static_sum, self.best_static):
            self.best_static, improved = static_sum, True
        if improved:
            self.since, self.best_t = 0, t
        else:
            self.since += 1


def _short_count(problem: DiscreteProblem, cells: np.ndarray) -> int:
    """The robots that have a free path to the goal and are outside the goal region (0 without a goal)."""
    if problem.goal_path is None:
        return 0
    d = cell_values(problem.goal_path, cells)
    return int(np.count_nonzero(np.isfinite(d) & ~(d <= problem.goal_region_radius)))


def _short_way(problem: DiscreteProblem, cells: np.ndarray) -> float:
    """The free-path distance (cells) to the goal summed over the robots :func:`_short_count` counts."""
    if problem.goal_path is None:
        return 0.0
    d = cell_values(problem.goal_path, cells)
    return float(d[np.isfinite(d) & ~(d <= problem.goal_region_radius)].sum())


def _short_of_goal(problem: DiscreteProblem, cells: np.ndarray) -> bool:
    """Some robot that has a free path to the goal is outside the goal region (never without a goal)."""
    return _short_count(problem, cells) > 0


def _arrived(problem: DiscreteProblem, cells: np.ndarray) -> bool:
    """Every robot that has a free path to the goal is in the goal region, and some robot has one: a swarm
    cut off from the goal has not arrived (it plans on by the energy, and ends converged, trapped or
    stalled)."""
    if problem.goal_path is None:
        return False
    d = cell_values(problem.goal_path, cells)
    reachable = np.isfinite(d)
    return bool(reachable.any() and np.all(d[reachable] <= problem.goal_region_radius))


def _no_progress(out: StepOutcome, tol: float) -> bool:
    """The step ends the plan: it moves nobody or lowers the energy by less than ``tol`` (relative)."""
    return out.moved == 0 or out.energy_before - out.energy_after < tol * max(1.0, abs(out.energy_before))


def plan_discrete(problem: DiscreteProblem, method: str = "icm", max_steps: int = 300, tol: float = 1e-6,
                  patience: int = 20, options: mrf_solvers.Options | None = None,
                  on_step: Callable[[int, StepOutcome], None] | None = None,
                  progress: str = "static", arrival: bool = False) -> DiscretePlan:
    """Iterate MRF steps from ``problem.start`` until the swarm energy converges.

    The keyword defaults are this function's own, not the config's (``arrival`` is off here, on in
    ``mrf.arrival``): :func:`mrfswarm.pipeline.plan` passes every one from the config, so call it that way
    (``method=cfg.mrf.method, max_steps=cfg.mrf.max_steps, tol=cfg.mrf.tol, patience=cfg.mrf.patience,
    progress=cfg.mrf.progress, arrival=cfg.mrf.arrival, options=mrfswarm.pipeline.mrf_options(cfg)``) to get
    the plan a run makes.

    Parameters
    ----------
    method
        A name in ``solvers.mrf.METHODS``.
    max_steps
        Step limit.
    tol
        Converged when one step lowers the energy (on its graph) by less than ``tol``
        relative to that energy (absolute below 1: the goal potential is exponential, so
        energies span many orders of magnitude across maps).
    patience
        Stalled after this many steps without progress; the paths end at the last step
        that made progress.
    progress
        What counts as progress (a name in :data:`PROGRESS_RULES`): ``"energy"``, a new
        minimum of the swarm energy; ``"static"``, that or a new minimum of the robots'
        static field sum_i rho_S(x_i). The swarm energy jumps whenever the k-NN graph's
        set of maximal cliques changes (it counts each robot once per clique), so a
        large swarm still filing toward its goal can go ``patience`` steps without a
        new energy minimum; the static sum has no such jumps.
    on_step
        Called after every step (progress bars, snapshots).
    arrival
        End the plan at the first step that has every robot with a free path to the goal
        inside the goal region (``"arrived"``, counted as converged). Without it the swarm
        settles into its formation until the energy stops decreasing or circulates
        (``patience``): on a 64 x 64 clutter map with 40 robots, 47 more steps of a few
        robots shuffling around the goal, flown as a slow tail.

    With ``problem.contested = "auto"`` the stage plans once per rule of :data:`AUTO_RULES` and
    returns the plan with the fewest robots short of the goal region, then (with robots short) the one that
    leaves them the shortest way to the goal in sum, then the one the sooner by :func:`flight_time`, then the
    first. Without the second rule a plan that stopped at its start (0 steps, no flight) beat one whose
    robots had come most of the way but not all (a bend of 1-cell corridor with the paper's patience rule).
    "queue" is planned only when the "shared" plan's robots wait :data:`QUEUE_WAITS` steps each or more. When the
    first plan has every robot at the goal, a
    later rule's plan ends after :data:`AUTO_STEP_CAP` times its steps, and a plan cut there is not kept (with
    ``arrival`` it has robots short of the goal; without, its swarm had not settled, though it may fly sooner by
    the model). The other plans tied with the kept one on the first two keys are its ``alternatives``
    (:attr:`DiscretePlan.alternatives`). ``on_step`` sees each plan's steps from 1.

    Raises
    ------
    ScenarioError
        A robot starts where the static field is not finite (no free path to the goal).
    ValueError
        ``progress`` not a rule, ``tol`` outside [0, 1).
    """
    if progress not in PROGRESS_RULES:
        raise ValueError(f"progress = {progress!r}: must be one of {', '.join(PROGRESS_RULES)}")
    if not 0 <= tol < 1:  # inf or NaN ended the plan after one step, "trapped" or "stalled" (mrf.tol's range)
        raise ValueError(f"tol = {tol!r}: must be in [0, 1) (a fraction of the swarm energy)")
    def one(p: DiscreteProblem, steps: int) -> DiscretePlan:
        return _plan_rule(p, method, steps, tol, patience, options, on_step, progress, arrival)

    if problem.contested != "auto":
        return one(problem, max_steps)
    kept: list[tuple[tuple[int, float, float], DiscretePlan]] = []
    cap = max_steps
    waits = np.inf  # per robot in the "shared" plan (AUTO_RULES has it before "queue")
    for rule in AUTO_RULES:
        if rule == "queue" and waits < QUEUE_WAITS:
            log.info('discrete stage, contested = "queue" not planned: the "shared" plan waits %.2f steps per robot '
                     "(fewer than %g)", waits, QUEUE_WAITS)
            continue
        plan = one(replace(problem, contested=rule), cap)
        if rule == "shared":
            waits = waits_per_robot(problem, plan.paths)
        key = (_short_count(problem, plan.paths[-1]), _short_way(problem, plan.paths[-1]),
               flight_time(problem, plan.paths))
        log.info("discrete stage, contested = %r: %d steps, %d robots short of the goal (%.1f cells of way left), "
                 "%s", rule, plan.n_steps, key[0], key[1],
                 f"{key[2]:.2f} s by the flight model" if (problem.pick or problem.flight) is not None
                 else f"{key[2]:.1f} cells of longest moves (no flight model: smoothing.speed is set)")
        cut = plan.stop_reason == "max_steps" and cap < max_steps
        if cut:
            log.info("discrete stage, contested = %r: cut at %d steps, %g x the first rule's (not mrf.max_steps = %d): "
                     "not kept", rule, cap, AUTO_STEP_CAP, max_steps)
        if not cut:
            kept.append((key, plan))
        if rule == AUTO_RULES[0] and key[0] == 0:  # arrived: a plan of many more steps would fly later
            cap = min(max_steps, int(np.ceil(AUTO_STEP_CAP * max(plan.n_steps, 1))))
    kept.sort(key=lambda kp: kp[0])  # stable: the first rule wins a tie
    (best_key, best), others = kept[0], list[DiscretePlan]()
    for key, plan in kept[1:]:
        if key[:2] == best_key[:2] and not any(np.array_equal(plan.paths, p.paths) for p in (best, *others)):
            others.append(plan)
    best.alternatives = tuple(others)
    return best


def waits_per_robot(problem: DiscreteProblem, paths: np.ndarray) -> float:
    """The steps robots stay in their cells short of the goal region along ``paths`` (T + 1, N, d), per robot (every
    stay counts without a goal)."""
    paths = np.asarray(paths)
    if len(paths) < 2:
        return 0.0
    stay = np.all(paths[1:] == paths[:-1], axis=2)
    if problem.goal_path is not None:
        stay &= ~(cell_values(problem.goal_path, paths[1:]) <= problem.goal_region_radius)
    return float(stay.sum()) / paths.shape[1]


def flight_time(problem: DiscreteProblem, paths: np.ndarray) -> float:
    """How long ``paths`` take to fly: seconds on the model ``contested = "auto"`` picks by (``problem.pick``, else
    ``problem.flight``), or without one the sum of each step's longest move (cells).

    The scenario's pick is the time grid's fast profile, the attempt every window tries first; the moderate one
    (``problem.flight``, which merges are judged by) picked the plan that flew soonest on 20 of 27 maps, the fast
    one on 23 (their misses 6.6 s and 2.3 s in sum; twenty-fifth session, docs/flight_quality.md), and its times
    are near the flown ones (the 300-robot crossing 65.0 s against 66.5 flown; moderate 77.3)."""
    if len(paths) < 2:
        return 0.0
    model = problem.pick if problem.pick is not None else problem.flight
    if model is not None:
        need, length = model.needs(paths)
        return float(model.duration(need.max(axis=1), length.max(axis=1)))
    return float(np.linalg.norm(np.diff(paths, axis=0), axis=2).max(axis=1).sum())


def _plan_rule(problem: DiscreteProblem, method: str, max_steps: int, tol: float, patience: int,
               options: mrf_solvers.Options | None, on_step: Callable[[int, StepOutcome], None] | None,
               progress: str, arrival: bool) -> DiscretePlan:
    """:func:`plan_discrete` with one contested rule."""
    pos = np.asarray(problem.start, dtype=np.intp).copy()
    _check_start(problem, pos)
    paths = [pos]
    energy: list[float] = []
    timings: dict[str, list[float]] = {s: [] for s in STAGES}
    steps: list[dict] = []
    converged = False
    reason = "max_steps"
    watch = _Progress(tol, progress, _static_sum(problem, pos))
    apart = separation_cells(problem)
    gt: dict[str, float] = {}
    weights = graph_weights(pos, problem.k, gt)
    base, congested, escalated = problem, 0, 0
    waited = np.zeros(len(pos), dtype=np.intp)  # the steps each robot has stayed in its cell
    if arrival and _arrived(problem, pos):  # there already: no step (one moved a robot for nothing)
        energy.append(swarm_energy(problem, pos, weights))
        converged, reason, max_steps = True, "arrived", 0
    for t in range(1, max_steps + 1):
        cong = base.congestion
        if cong is not None and t > 1 and (t - 2) % cong.every == 0:
            stalled = cong.stalled(paths[-2], pos)
            new = cong.fields(pos[stalled]) if stalled.any() else None
            problem = base if new is None else replace(base, static=new[0], goal_distance=new[1])
            congested += new is not None
        trim = trim_mask(problem, paths)
        try:
            out = mrf_step(problem, pos, method, options, weights, gt, trim, waited)
            escalate = problem.escalation
            if escalate is not None and escalate != method and _no_progress(out, tol) and _short_of_goal(problem, pos):
                joint = mrf_step(problem, pos, escalate, options, weights, gt, trim, waited)
                if joint.moved and joint.energy_after < out.energy_after:
                    out, escalated = joint, escalated + 1
        except SolversError as e:  # which step and plan: exact's refusal after 27 s of planning said neither
            e.args = (f"MRF step {t} (contested = {problem.contested!r}): {e}", *e.args[1:])
            raise
        if t == 1:
            energy.append(out.energy_before)
            watch.best = out.energy_before
        for s in STAGES:
            timings[s].append(out.timings[s])
        steps.append({
            "iterations": out.result.iterations,
            "repaired": out.result.repaired,
            "lower_bound": out.result.lower_bound,
            "moved": out.moved,
            "decrease": out.energy_before - out.energy_after,
            "separated": int(np.count_nonzero(nearest_neighbour_cells(out.positions) > apart)),
        })
        if on_step is not None:
            on_step(t, out)
        if out.moved == 0:
            converged, reason = True, "converged"
            for s in STAGES:  # a step that moved nobody is not part of the path
                timings[s].pop()
            steps.pop()
            break
        waited = np.where(np.all(out.positions == pos, axis=1), waited + 1, 0)
        pos = out.positions
        paths.append(pos)
        gt = {}
        weights = graph_weights(pos, problem.k, gt, previous=weights)
        energy.append(swarm_energy(problem, pos, weights))
        if out.energy_before - out.energy_after < tol * max(1.0, abs(out.energy_before)):
            converged, reason = True, "converged"
            break
        if arrival and _arrived(problem, pos):
            converged, reason = True, "arrived"
            break
        # progress is measured on the scenario's own field (a congested one changes every few steps)
        watch.record(t, energy[-1] if problem is base else swarm_energy(base, pos, weights), _static_sum(base, pos))
        if watch.since >= patience:
            # the steps since the last progress only circulate: the plan ends there
            reason, best_t = "stalled", watch.best_t
            del paths[best_t + 1:], energy[best_t + 1:], steps[best_t:]
            for s in STAGES:
                del timings[s][best_t:]
            break
    if converged and _short_of_goal(problem, paths[-1]):  # a fixed point short of the goal is not convergence
        converged, reason = False, "trapped"
    log.info("discrete stage: %d steps, %s", len(paths) - 1, reason)
    stacked = np.stack(paths)
    merged = dropped = straightened = 0
    if problem.drop_loops:
        stacked, dropped = drop_loops(stacked, problem.downwash)
    if problem.straighten:
        stacked, straightened = straighten(stacked, problem.free, problem.downwash)
    if problem.merge_waits:
        stacked, merged = merge_waits(stacked, problem.downwash, problem.flight)
    bad = discrete_violations(stacked, problem.free, downwash=problem.downwash)
    if bad:  # a bug in the planner or an optimizer, never something to return
        raise AssertionError("discrete safety invariant violated: " + "; ".join(bad))
    return DiscretePlan(
        paths=stacked,
        energy=np.array(energy),
        converged=converged,
        timings={s: np.array(v) for s, v in timings.items()},
        steps=steps,
        stop_reason=reason,
        merged_waits=merged,
        dropped_loops=dropped,
        straightened=straightened,
        congested_fields=congested,
        contested=problem.contested,
        escalated=escalated,
    )
