"""The window loop: receding-horizon smoothing on safe regions, every window certified.

Windows. With horizon H and execution fraction e, E = round(e H) steps are executed per
window. ``seam = "continuous"`` (default): window [a, a + H] starts in the state
(position and derivatives up to q - 1, jerk for min-snap) the previous window's
trajectory has at step a and ends at rest on the discrete position of step a + H; its
first E steps are flown and the next window starts at a + E, so the flight is
continuous up to jerk with no stop inside it. ``seam = "rest"`` (the paper's variant):
window [a, a + E] from rest to rest on the discrete positions.

Each window is the problem of :mod:`mrfswarm.continuous.formulation` over its steps:
regions, relative safe corridors and limit polygons on Bernstein control points. Robots
linked by no corridor in the window are independent problems (one QP per interaction
group). Step durations are chosen per window (nominal: longest move over ``speed``) and
fixed once a step is flown.

Recursive feasibility. Let the previous window have planned up to step b' (ending at rest
on the discrete position there). Its trajectory over [a, b'], followed by every robot's
own discrete move flown rest to rest on the new steps, satisfies every constraint of the
new window once the new steps last at least the witness durations
(:func:`~mrfswarm.continuous.time_grid.witness_durations`). So a window is tried at
nominal durations; then with the previous window's durations on the overlap; then with
the new steps slowed (x1.5 at a time) up to the witness durations; and if the solver
still fails, the witness itself is flown. A window therefore never fails for lack of a
feasible point; only a certificate that rejects the witness (a bug) stops a run, loudly.

Holds. A robot that has arrived for good (no move left in the discrete plan) is held still
at its cell from :data:`HOLD_SETTLE` steps after its last move: the drifting attempts are
tried first with its box shrunk to the cell's centre (equality rows) and the creep rows, then
with the holds alone, and without the holds where they fail, so a hold never slows a window. Without them minimum snap let arrived robots
drift through their boxes while the swarm arrived, with a near-stop at every turn (flight_quality
bench, stops per robot: open field 0.12 -> 0.06, aisles30 0.27 -> 0.17, the same makespans).
Where the holds fail and the window flies without them, the robots that its solution brings
against a corridor's plane (a held robot cannot make way for a neighbour swinging back past it),
then also those not at rest at the window's start, are released and the others held
(:meth:`RecedingHorizon._releases`): clutter40's late windows, of two steps per piece, failed
with every hold, and its stops went 0.25 -> 0.12 per robot with the same flight.

Pieces per robot (``smoothing.max_pieces``, :mod:`mrfswarm.continuous.merge_pieces`): when
the steps left exceed the pieces left, a window flies its E steps in fewer pieces (its
share of the pieces left), every robot the same; if no duration of the ladder gives a
certified merged window, it is planned with twice the pieces, and so on down to one piece
per step (and its witness). The trajectories are assembled from the step pieces and each
block merged into one piece; the certificate splits them at the steps again.

Certification. Every accepted window, and the assembled flight, is certified by
:func:`~mrfswarm.continuous.certificate.certify_pieces` (regions, relative hulls,
limits: exact, on control points); the regions' clearance from obstacles is checked once.
Dense sampling (``smoothing.check_rate_hz``) is an optional independent check.

Time refinement (``smoothing.time_refinement``): after a window is accepted, its step
durations become the variables of an NLP (:class:`TimeAllocation`) started from the QP's:
the window problem's optimal snap at those durations plus ``time_weight`` x duration, with
the exact gradient from the QP's multipliers (envelope theorem) and the symbolic pieces'
derivative in their durations. ``smoothing.refinement = "scaling"`` (default) shortens
them by a few QP solves that rescale each step by its multipliers
(:mod:`mrfswarm.continuous.duration_scaling`); ``"nlp"`` solves the NLP by the backend
``smoothing.nlp`` of :data:`solvers.nlp.BACKENDS` (Ipopt by default). The refined solution
is accepted if it certifies and lowers that cost. Refining one window at a time is greedy: a
window refined can leave the swarm faster than the next window's profiles can take over from,
so that the next one fails its fast profile or even flies the previous window's braking tail;
that next window is then planned again from the unrefined solution, and the pair that flies
sooner is kept (``RecedingHorizon._undo_refinement``). A refined run also tries its own attempts, whether or
not the refinement keeps a point: every attempt keeps the first step the window before planned
(``RecedingHorizon._follow``), and a window bisects between its certified attempt and the last faster one that
failed (``RecedingHorizon._bisect``). So a refined run with no window refined (``refined_windows`` 0) flies
another flight than the default's (the arena by L-BFGS-B: 5.06 s against 5.12).
"""

from __future__ import annotations

import dataclasses
import logging
import math
import os
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field

import numpy as np

import solvers.nlp
import solvers.qp
from mrfswarm.config import SmoothingConfig
from mrfswarm.continuous.certificate import Certificate, certify, certify_pieces
from mrfswarm.continuous.duration_scaling import scale_durations, step_factors
from mrfswarm.continuous.formulation import (
    LIMIT_ORDERS,
    LIMIT_PARTS,
    WindowSpec,
    hermite_trajectory,
    limit_polytope,
    piece_maps,
)
from mrfswarm.continuous.merge_pieces import (
    block_sizes,
    merge_trajectories,
    merged_knots,
    project_blocks,
    step_pieces,
    window_pieces,
)
from mrfswarm.continuous.regions import (
    Regions,
    Separations,
    arrival_holds,
    build_regions,
    hold_regions,
    interaction_groups,
    region_clearance,
    separations,
)
from mrfswarm.continuous.sampled_check import SampledCheck, check_positions, uniform_times
from mrfswarm.continuous.time_grid import (
    FlightModel,
    SwarmProfile,
    braking_distance,
    drift_waits,
    motion_profile,
    next_moves,
    nominal_durations,
    reachable_speed,
    rest_times,
    witness_durations,
)
from mrfswarm.continuous.window_cache import WINDOWS
from mrfswarm.errors import ConfigError, ScenarioError, UnsafeTrajectoryError
from mrfswarm.geometry import downwash_scale
from mrfswarm.maps import OccupancyGrid
from mrfswarm.maps.obstacles import ObstacleIndex
from mrfswarm.pools import process_pool, usable_workers
from mrfswarm.trajectory import PiecewisePolynomial
from mrfswarm.trajectory.bernstein import control_point_matrix
from mrfswarm.trajectory.piece_stack import map_coefficients
from mrfswarm.trajectory.retiming import max_derivative_norm_all
from solvers.errors import SolveFailedError, SolverError
from solvers.nlp import NLPProblem
from solvers.nlp import Options as NLPOptions
from solvers.qp import Options as QPOptions

log = logging.getLogger(__name__)

#: Tightening of the QP's region and corridor rows (metres) and, relatively, of its limits.
MARGIN = 1e-6
#: The same in windows with pieces spanning several steps: projecting a solution onto one polynomial
#: per block (merge_pieces.project_blocks) moves control points by the solver's tolerance on the merge
#: rows, amplified by the block (up to 2.4e-6 m measured on a slow 8-step window), which MARGIN did not cover.
MERGED_MARGIN = 1e-5
#: The time unit of a window with pieces spanning several steps, as a share of the geometric-mean nominal step
#: (the unit of a window whose pieces are its steps), on fine cells (more than :data:`FINE_BRAKING_STEPS` cells to
#: brake in, where :func:`braking_horizon` lengthens the default windows), whose merge rows are then also scaled to unit norm
#: (``WindowSpec.unit_merge_rows``). Its merge rows (formulation: Taylor coefficients q..D equal at a merged knot)
#: in the usual unit, where a step lasts about 1, left piqp's interior point stalling on feasible windows (dual
#: residual stuck near 1e-4, MAX_ITER_REACHED; clarabel: InsufficientProgress; a helper's analysis, 2026-11-29):
#: two robots crossing 5 m of 0.1 m cells in 31 pieces flew 13.0 s (18.9 s in windows of 36 steps). Measured
#: (in-process, that crossing / a tour's 8 robots through a 0.4 m door on 0.1 m cells at v_max 3, 8.4 s before):
#: 0.05: 4.70 / 4.43 s (planning 13.8 s for the second); 0.1: 4.82 / 4.45 s (7.5 s); 0.15: 4.90 / 13.15; 0.2:
#: 5.19 / 18.6. Not on every flight: on the flight-quality maps (1 m cells, windows not lengthened) the unit 0.2 flew
#: clutter40 1.28 -> 1.39 x by default (refined 1.19 -> 1.22), the aisles 1.29 -> 1.28 (flight_quality.py
#: --baseline 2ce447c); gated, those maps fly the same.
MERGED_TIME_UNIT = 0.1
#: Cells of braking (:func:`braking_steps`) above which the cells count as fine: merged windows get
#: :data:`MERGED_TIME_UNIT`. The default windows of 8 steps, half of them flown, brake in 4. The unit was given
#: only where the windows were lengthened, so a user's own long windows on fine cells went without it: the 5 m
#: crossing above in one window of 48 steps (``smoothing.horizon = 48``) failed every profile and flew 37.5 s
#: (4.8 s in the lengthened windows of 36; 5.0 s with the unit).
FINE_BRAKING_STEPS = 4
#: With a cruise ``speed`` given, the nominal time grid speeds up and slows down at this fraction of a_max.
NOMINAL_ACCELERATION = 0.25
#: Without one (the default), each robot's speed profile cruises at this fraction of v_max (the rest is the
#: room the smooth trajectory needs around the profile's corners: min-snap overshoots a trapezoid's speed) and
#: accelerates at this fraction of what the limits allow over a speed change (see motion_acceleration). A
#: window tries the bold profile first, then the cautious one, then slows down. Measured on the maps of
#: experiments/bench/flight_quality.py: the bold one alone is accepted in most windows of open maps (open field
#: of 50: makespan 1.57 x the bound against 2.00), the cautious one alone in every window of every map.
CRUISE = 0.95
ACCELERATION = 2.0
#: A fast profile tried before the bold one, on the steps a window flies (its tail, planned and not flown, is the
#: bold profile's): cruise at v_max, 1.5 times the bold acceleration. The QP keeps robots in their regions, not on
#: the profile, so a robot may lag its cells by what the regions' growth leaves, and many windows take it.
#: Measured with the stretched attempts against c30ec68 (flight-quality bench, 2026-11-27, one run): doorway 1.56 ->
#: 1.41 x the bound, forest 1.80 -> 1.62, rooms 1.50 -> 1.41, open field 1.32 -> 1.24, aisles30 1.68 -> 1.57,
#: arena 1.78 -> 1.58, clutter40 2.45 -> 2.43, at 1.0-2.1 times the planning. Fast on the whole window (its tail
#: too): clutter40 2.34, but it failed more often and planned the open field in 3 times the time. At 0.95 v_max and 3
#: times: clutter40 2.44, arena 1.63; at 0.95 and 4 times the arena's windows all failed it (1.78); as the bold
#: profile itself (3 times, no fast one), its moderate profile became bolder too and clutter40 flew 2.67.
#: The acceleration factor 4 (was 3) measured best of 3, 3.5, 4, 5, 6 with the octagon limits; with the 16-gon
#: (formulation.POLYGON) against 3 (wr.py runs, 2026-11-27): doorway 13.29 -> 12.95 s, aisles30 43.6 -> 42.8,
#: arena 7.19 -> 6.88, cross300 67.6 -> 66.6, the rest within 1 % (clutter40 89.9 -> 90.2).
FAST_CRUISE = 1.0
FAST_ACCELERATION = 4.0
CAUTIOUS_CRUISE = 0.9
CAUTIOUS_ACCELERATION = 1.0
#: Share of a cell's room (its side less the robot's diameter) a robot may drift through during a
#: single-step wait, in the bold and moderate profiles (the cautious one stops there).
DRIFT = 1.0
#: In the attempts of the bold and moderate profiles, a robot in a run of up to CREEP_WAITS waits between two
#: moves that turn by less than 90 degrees (``time_grid.drift_waits``) keeps moving along its way at least this
#: fast (m/s; twice the speed below which the flight_quality bench counts a stop), where its regions allow: the
#: window's QP gets rows on its velocity control points, and where they make the attempt fail the same
#: durations are tried without them. Measured (flight_quality bench, stops per robot): clutter40 1.00 -> 0.93,
#: open field 0.30 -> 0.28, the same makespans, big200 the same flight. Letting the time grid also drift
#: through those runs (not only single waits) flew most maps 2-3 % sooner and clutter40 with 0.75 stops, but
#: big200 4.6 % later (3.33 x the bound against 3.18) and the refined arena 1.73 x against 1.62. Runs of up to 8
#: waits rather than 5: the seven random clutter maps of clutter40's kind 0.15 -> 0.12 stops per robot on average,
#: the two above 0.25 down to 0.225 and 0.25 (0.3 and 0.5 % later), the mean makespan 1.419 -> 1.421 x the
#: bound; the nine flight-quality maps the same flights; big200 1.21 -> 1.25 stops, the same makespan.
CREEP_SPEED = 0.1
CREEP_WAITS = 8
#: Steps an arrived robot has to brake to rest at its final cell before it is held there
#: (:func:`~mrfswarm.continuous.regions.arrival_holds`; 1 and 3 flew the same flight-quality maps as soon, with
#: stops within noise of 2), and the metres its held box leaves it besides the rows' tightening.
HOLD_SETTLE = 2
HOLD_ROOM = 2e-5
#: Metres: a held robot that a solution without the holds brings this close to a corridor's plane (beyond the
#: corridor's distance and slack) is released where the holds fail (RecedingHorizon._releases).
RELEASE_GAP = 0.01
#: The attempts' profiles in order: (name, cruise, acceleration): the fast one, the bold one (``"nominal"``: its
#: durations are the window's nominal ones), and a moderate one between the bold and the
#: cautious, whose durations the slower attempts start from. The moderate one gained 3 to 9 % of makespan in
#: clutter (flight_quality bench: clutter40 3.38 -> 3.07 x the bound, aisles30 1.95 -> 1.84, forest 1.83 ->
#: 1.78). Refinement skips it: refined from the moderate durations, a corridor window left the swarm in a
#: state the next window could only leave at rest (27.8 s against 22.4 from the cautious ones).
PROFILES = (("fast", FAST_CRUISE, FAST_ACCELERATION),
            ("nominal", CRUISE, ACCELERATION),
            ("moderate", 0.5 * (CRUISE + CAUTIOUS_CRUISE), float(np.sqrt(ACCELERATION * CAUTIOUS_ACCELERATION))),
            ("cautious", CAUTIOUS_CRUISE, CAUTIOUS_ACCELERATION))


def export_slack(resolution: float, radius: float) -> float:
    """Metres kept free for the compressed export's rounding: :data:`EXPORT_SLACK`, or a quarter of what a cell
    leaves around a robot (the rest-to-rest witness keeps that much, so a window never lacks a feasible point)."""
    return float(min(EXPORT_SLACK, 0.25 * (0.5 * resolution - radius)))


def drift_room(resolution: float, radius: float) -> float:
    """Metres a robot may drift through a single-step wait in the bold profiles (:data:`DRIFT` of its cell's room)."""
    return DRIFT * max(0.0, resolution - 2 * radius - 2 * export_slack(resolution, radius))


def flight_model(cfg: SmoothingConfig, resolution: float, radius: float, profile: str = "moderate") -> FlightModel | None:
    """A profile of the default time grid (:data:`PROFILES`) as a :class:`FlightModel` (None with a cruise ``speed``
    set).

    Merged waits are judged by the moderate one (:mod:`mrfswarm.discrete.merge_waits`): in clutter most windows fly
    it, and judged by the bold one clutter40 kept fewer merges and flew 2.53 x the bound instead of 2.45 (doorway,
    rooms, aisles, arena alike). ``contested = "auto"`` picks its plan by the fast one
    (:attr:`mrfswarm.discrete.planner.DiscreteProblem.pick`).
    """
    if cfg.speed is not None:
        return None
    name, cruise, acc = next(p for p in PROFILES if p[0] == profile)
    return FlightModel(resolution, cruise * cfg.v_max, motion_acceleration(cfg.v_max, cfg.a_max, cfg.j_max, acc),
                       drift_room(resolution, radius))


def braking_horizon(cfg: SmoothingConfig, speed: float, resolution: float) -> int:
    """Steps per window: ``cfg.horizon``, or more where the steps a window plans and does not fly could not hold
    the braking from ``speed`` (the profiles' top speed) to rest, which every window ends at.

    The fast attempt's unflown steps brake as the bold profile does (its acceleration, the jerk limit):
    :data:`BRAKING_ROOM` times that distance in cells, over the share of the window not flown (1 - ``execution``).
    On 1 m cells at 2 m/s (1.4 m) or 0.25 m cells at 1 m/s (0.46 m) the default 8 steps hold it; on 0.1 m
    cells at 2 m/s they did not: every window's tail braked from at most 0.86 m/s, its faster attempts had no
    solution, and two robots crossing 5 m (47 steps, one piece each: ``max_pieces = 0``) flew 10.8 s at v_max 2
    against 6.4 s at v_max 1; in windows of 36 steps 4.7 s. With the 31 pieces of a Crazyflie the same crossing
    flew 13.0 s in windows of 8 steps, and 18.9 s in windows of 36 until the merged windows got their own time
    unit (:data:`MERGED_TIME_UNIT`): 4.8 s now.
    """
    if cfg.seam == "rest" or cfg.execution >= 1:
        return cfg.horizon
    return max(cfg.horizon, math.ceil(braking_steps(cfg, speed, resolution) / (1 - cfg.execution)))


def braking_steps(cfg: SmoothingConfig, speed: float, resolution: float) -> int:
    """Cells a window's tail brakes from ``speed`` to rest in: :data:`BRAKING_ROOM` times the distance of the
    jerk-limited braking at the bold profile's acceleration (2 on 1 m cells at 2 m/s, 3 on the arena's 0.25 m cells
    at 1 m/s, 18 on 0.1 m cells at 2 m/s)."""
    acc = motion_acceleration(speed, cfg.a_max, cfg.j_max, ACCELERATION)
    return math.ceil(BRAKING_ROOM * braking_distance(speed, acc, cfg.j_max) / resolution)


def motion_acceleration(v_max: float, a_max: float, j_max: float, fraction: float = ACCELERATION) -> float:
    r"""The acceleration of the default speed profiles: a_max, or less where jerk limits it.

    A jerk-limited change of speed by v_max takes at least :math:`2\sqrt{v_{max}/j_{max}}`
    (an S-curve with no constant-acceleration phase), an average acceleration of
    :math:`\sqrt{v_{max} j_{max}}/2`; the profiles use :data:`ACCELERATION` of the smaller of that and a_max.
    """
    return fraction * min(a_max, 0.5 * math.sqrt(v_max * j_max))


#: The time refinement's NLP settings (the config's ``[smoothing.nlp_options]`` go over these): each iteration
#: solves the window's QP a few times; on
#: corridor.toml 12 Ipopt iterations keep nearly all of 25's gain (makespan 21.4 s against 21.3) at a fifth of the QPs.
NLP_OPTIONS = NLPOptions(tol=1e-4, max_iter=12)
#: Options of the window QPs unless the caller gives others (the config's [smoothing.qp_options] go over
#: these). No equilibration: the formulation scales its variables already (time normalized per window),
#: and Ruiz scaling made piqp declare feasible windows infeasible (14 of 220 sampled QPs of a
#: 100-robot crossing and a 1000-robot window, each one a needless slower attempt or a rest-to-rest witness) and cost it 3x the
#: iterations; osqp and clarabel also converge faster without it.
QP_OPTIONS = QPOptions(eps_abs=1e-7, eps_rel=1e-7, max_iter=50000, scaling=False)
#: Metres every region and corridor row keeps free for the Crazyflie's compressed format, which moves control
#: points by up to its error bound (1.8 mm on the arena, 1.9 mm on the corridor, 2026-11-29: mrfswarm.export.cflib_), so that
#: the rounded flight certifies with the robot radius itself.
EXPORT_SLACK = 3e-3
#: Share of (v_max, a_max, j_max) the window QP's limit rows keep free for the same rounding. Along the grid's
#: moves a cruise reaches the limit polygon's vertex, v_max itself (formulation.POLYGON), and a millimetre of
#: rounding then takes a velocity control point over it: the corridor's compressed flight reached 2.002 m/s > 2
#: and did not certify. With 0.25 % kept free it did; at 0.5 % the flight-quality cases flew as without (the
#: same makespans within 0.4 %; 2026-11-27). Acceleration and jerk keep none: there the rounding search
#: (mrfswarm.export.cflib_) finds roundings within the limits on the corridor as it did before.
EXPORT_LIMIT_SLACK = (5e-3, 0.0, 0.0)
#: Robots per chunk: independent groups are packed into QPs of about this many robots. Small chunks cost less
#: than one large QP even in one process: piqp's iterations grow with the hardest robot of a QP, and a failing
#: attempt stops after the chunk that failed last time (``_solve_chunks``). 12 instead of 64, default planning on
#: 2 cores (2026-11-28, one warm process per map, two runs; the plans of ``mrf.contested = "auto"``): the open
#: field 12.4 -> 6.5 s (one worker: 12.4 -> 9.1), clutter40 8.3 -> 6.2, aisles30 3.4 -> 2.6, 200 robots in
#: clutter 103.9 -> 96.2, the 300-robot crossing 33.9 -> 29.0, the 1000-robot crossing 200.2 -> 182.6; 8 robots
#: the same as 12, 16 the open field 7.6 s, 32 10.6 s. The flights: clutter40 46.99 -> 47.13 s, aisles30 36.80
#: -> 36.85, the rest of the bench within 0.1 %; seven clutter maps +0.95 % in sum (seed 3 54.06 -> 58.60 s: its
#: first window's cautious attempt runs to piqp's iteration cap in a chunk of 10; docs/flight_quality.md).
CHUNK_ROBOTS = 12
#: Swarms at least this large (two chunks or more) solve their chunks in worker processes (forked, so
#: cheap to start: 100 robots on 2 cores, smoothing 6.1 s -> 5.0 s with chunks of 64).
PARALLEL_ROBOTS = CHUNK_ROBOTS + 1
#: Rounds of lazy constraint generation before every row is switched on.
MAX_ROUNDS = 12
#: Limits that need steps this many times longer than at REFERENCE_SPEED are refused as unreachable.
MAX_SLOWDOWN = 1e3
#: m/s; see MAX_SLOWDOWN.
REFERENCE_SPEED = 1.0
#: Share of the QP backend's iteration budget (``QPCapabilities.iteration_budget``) given to the bold and moderate
#: profiles' attempts, which a slower attempt follows (the time refinement's trial points: :data:`TRIAL_BUDGET`). PIQP solves window QPs in 15 iterations on average (at most
#: 96 measured), and the attempts that fail run its cap of 120: on the 40 robots in clutter of the flight-quality
#: bench, those failures were 58 % of the QP time. At 40 iterations clutter40, forest and aisles30 planned the same
#: flights in less time (clutter40 10.1 s -> 7.0), open50 one window differently (makespan 41.02 s -> 41.11, 11.0 s
#: of planning -> 8.1).
OPTIMISTIC_BUDGET = 1 / 3
#: Share of the iteration budget given to the time refinement's trial points: a trial without a solution is only a
#: step the refinement does not take. At 1/3 (40 of PIQP's 120, twice what a solved window takes) clutter40
#: refined planned 51.4 s -> 31.0 against the full budget (makespan 68.5 s -> 69.2; 2026-11-26). 1/3 -> 1/4 (30
#: iterations; 2026-11-29, flight_quality.py --baseline 0ba6d1a, the machine loaded by a second job): clutter40
#: refined 43.07 -> 43.81 s (1.18 -> 1.20 x), its planning over the default's 3.10 -> 2.60 x (median of three
#: rounds); clutter40's maps of seeds 2-6 and the rest of the bench the same flights within 0.3 % (the forest 21.82
#: -> 21.86 s, the open field 28.92 -> 29.00); seed 7 47.19 -> 47.65 s (0.12 -> 0.05 stops per robot), its
#: planning 27.7 -> 23.6 s. At 1/6 clutter40 flew 46.38 s. The NLP backends' trial points keep OPTIMISTIC_BUDGET: at
#: 1/4, Ipopt at time weight 10000 flew the arena 5.38 -> 5.52 s (its line search meets more points without a
#: solution).
TRIAL_BUDGET = 1 / 4
#: Seconds by which a refined window may outlast its QP's durations and still count as "not longer": the scaling caps
#: its points at the QP's sum (``duration_scaling.scale_durations``, ``total``), which rounding can pass by 1e-15 s;
#: compared exactly, refined clutter40 lost two of its 17 windows' refinements that way (2026-11-28, tenth session).
#: Also by which no step of a refined point may differ from the QP's for it to count as the QP's own durations, not
#: a refinement: compared exactly, the refined arena's third window counted in ``refined_windows`` at steps 6e-17 s
#: shorter (the cap's rounding), its snap lower by the QP's tolerance.
SAME_LENGTH = 1e-9
#: A hopeful attempt with creep rows or holds tries its plain durations first once this many times the run's count
#: of attempts with no solution without them exceeds its count of attempts solved with them: the rows only add
#: constraints, so where the plain durations have no solution the variants are not solved (they would fail, each
#: to the budget above, about twice a solved one's iterations); where they are solved with them, the plain solve is
#: one more. Measured (flight_quality.py --baseline 39d3468, 2026-11-28, eighth session): the open field's planning
#: 7.6 -> 6.2 s, clutter40 9.5 -> 8.2 s, the other maps the same time, the same flights but clutter40's (52.70 ->
#: 52.73 s: a hopeful solve can also fail for its iteration budget, and the plain solve's lazy rows change later
#: solves; 2 of its 17 windows flew another attempt). Plain first from the start made aisles30 2.0 -> 2.35 s. Not
#: in a refined run: there the plain solve's rows are carried into the refinement's trial points (each then started
#: from the accepted QP's rows), which flew refined clutter40 46.86 -> 47.52 s for 3 % less planning.
PLAIN_FAIL_WEIGHT = 2
#: Suffix of the fast attempt with its first step as the window before planned it, which the default tries
#: among its attempts (:meth:`RecedingHorizon._follow`): measured in the session of 2026-11-28 (fifth), see
#: docs/flight_quality.md, "What changed".
FOLLOWED = ", first step as planned"
#: Powers of the stretch (see RecedingHorizon._stretched) tried, in this order, before the cautious profile: a
#: window whose faster profiles fail flies the bold profile's durations stretched by half the stretch (in the
#: logarithm), or by all of it, where their flown steps are shorter than the cautious profile's. Measured on the
#: flight-quality bench (2026-11-27, before the fast profile): forest 1.80 -> 1.64 x the bound, rooms 1.50 -> 1.49,
#: aisles30 1.68 -> 1.67, open50 1.32 -> 1.31, clutter40 2.45 -> 2.41, the other maps the same. Tried before the
#: moderate profile as well, clutter40 flew 2.50: a window flown faster left states the next windows could leave
#: only at the cautious profile. Stretched from the fast profile's durations, two robots on a straight line of 24
#: cells flew 1.29 x their time at v_max instead of 1.23 (the first window's stretch left the next only its
#: previous plan); from the bold one's, 1.23, and the maps within 2 % (forest 1.62 against 1.59).
STRETCH_POWERS = (0.5, 1.0)
#: The flight's last window tries its fast durations with the last step this many times longer, in this order,
#: after the fast attempt itself and before the bold one: the fast profile brakes to the final rest at
#: FAST_ACCELERATION, and where that is a little too short for the jerk limit the window fell back to the
#: bold durations, every step longer (the arena flew its last four steps in 1.95 s instead of 1.70, at
#: 1.50 x the bound; 1.44 x now; corridor 20.70 -> 20.51 s, doorway 11.72 -> 11.53, rooms 26.93 -> 26.74,
#: the other flight-quality maps the same).
FINAL_BRAKING = (1.1, 1.25)
#: The other windows try their fast durations this many times longer on the flown steps, in this order, after
#: the fast attempt and before the bold one (whose acceleration is half the fast one's; flight_quality.py
#: --baseline 3193ad4, CSVs experiments/bench/results/flight_quality_vs_3193ad4.csv, ..._big3d_vs_3193ad4.csv):
#: clutter40 55.43 -> 53.45 s (1.52 -> 1.46 x the bound), the open field 1.14 -> 1.12, rooms 26.74 -> 26.52 s,
#: 200 robots in clutter 2.22 -> 2.07 x with 1.76 -> 1.43 stops per robot, refined aisles 1.28 -> 1.26,
#: refined clutter40 0.28 -> 0.07 stops, but the refined open field 0 -> 0.2 stops; the 3-D cases the same.
#: A hold never slows a window, so where the fast durations made longer fly only without the holds they are
#: flown so, sooner than the bold ones with the holds (tests/continuous/test_hold.py's arrived robot drifts
#: there at up to 0.36 m/s, the bold attempt held it).
FAST_SLOWER = (1.05, 1.1)
#: The flight's first window (the swarm at rest) also tries the fast durations with each flown step at least what
#: the fastest jerk-limited start from rest needs over the swarm's progress (``time_grid.rest_times``), times this
#: factor, before the first attempt whose flown steps last longer. The fast and bold profiles start at a constant
#: acceleration that the jerk limit does not allow, and where they fail the first window flew the moderate
#: profile, cruising at 0.925 v_max. At 1.0 the window QP, whose control points keep inside the limit polygons,
#: had no solution on the arena's first window (piqp: primal infeasible); at 1.05 (flight_quality maps, one run,
#: 2026-11-29): the doorway 10.50 -> 10.46 s (refined 10.62 -> 10.45), aisles30 35.99 -> 35.88 (32.36 -> 32.26),
#: the corridor, forest, rooms, trap, open field, clutter40 and arena the same flights (their first windows fly
#: a faster attempt, or the moderate one still); a second try at 1.1 or 1.15 changed none of them.
JERK_START = 1.05
JERK_START_NAME = "jerk-limited start"
#: Factor by which new steps are slowed per attempt after the nominal ones fail.
SLOWDOWN = 1.5
#: Bisections of a refined window between its certified attempt and the last faster one that failed
#: (:meth:`RecedingHorizon._bisect`). The ladder's rungs lie a few per cent to 1.5 x apart, and a window that fits
#: between two flew the slower one. Measured, refined (flight_quality.py --variants default,refined --baseline
#: 8324e2b --baseline-variants default,refined, one run, CSV flight_quality_bisection.csv): clutter40 43.81 -> 43.36 s,
#: aisles30 32.26 -> 31.91 (but 0.03 -> 0.10 stops per robot), the open field 29.00 -> 28.83, rooms 24.21 -> 24.09,
#: the trap 24.76 -> 24.62, the corridor, doorway and arena the same, the forest 21.86 -> 21.92 (a window flown sooner
#: left a state the next could leave only slower); the refined planning over the default's: clutter40 2.47 -> 2.88 x,
#: aisles30 2.03 -> 2.40, the others within 0.2 x. Two bisections (in-process, one run each): clutter40 43.42 s in
#: 1.5 times the planning, aisles30 31.84, the arena 5.482 -> 5.476, the others as one. Not in the default: bisecting
#: its windows twice flew the maps 0.2-2 % sooner (the arena 5.78 -> 5.66 s, clutter40 46.73 -> 47.09 later; CSV
#: flight_quality_bisection_every_window.csv) but cost the big swarms' planning 50-60 % (200 robots in clutter
#: 111 -> 163 s for a flight 2 % sooner, the 1000-robot crossing 241 -> 392 s for 0.1 %; CSV
#: flight_quality_bisection_every_window_big.csv).
BISECTIONS = 1
#: Room a window's unflown steps give the braking from the cruise to rest (:func:`braking_horizon`), over the
#: distance of the jerk-limited braking at the bold profile's acceleration: the window QP's snap-optimal braking
#: within given durations needs more (0.1 m cells at 2 m/s: windows whose tail held 12 cells of its 13 failed).
BRAKING_ROOM = 1.25
#: A flight of at most this many horizons' steps is re-timed as a whole once its windows are planned
#: (:meth:`RecedingHorizon._retime`): where a flight spans few windows, their tails, each braking to rest for the
#: next window's sake, weigh most. Measured (flight_quality.py --variants default,refined --baseline bc673d4
#: --baseline-variants default,refined, CSV flight_quality_retime.csv): the arena (16 steps) 5.78 -> 5.43 s
#: (1.34 -> 1.26 x its bound), refined 5.48 -> 5.37 (1.27 -> 1.246 x), its planning 0.5 -> 1.5 s; the other maps
#: are longer and fly the same. Longer flights gain less for a whole-flight QP each try (in-process, one run each:
#: the doorway's 17 steps and the trap's 38, one piece per step, 1 % at x0.99, 0.4-0.5 s; the maps whose pieces
#: merge for a Crazyflie's memory, none at x0.99).
RETIME_HORIZONS = 2
#: The first attempt of a window, where it is sooner than the fast one: the fast profile with each robot leading or
#: lagging its cell at the flight's inner knots by up to half its drift room (:func:`drift_room`: as far from the
#: cell's centre as the robot still keeps its room), :func:`~mrfswarm.continuous.time_grid.lead_needs`. A step
#: lasts as long as its longest move, so a robot merging diagonally into a file slowed the whole file to 0.71 of
#: v_max; leading, it starts its move in the wait before. Where it fails, the rows its rounds switched on are
#: dropped again (see :meth:`RecedingHorizon._plan_window`). Measured in docs/flight_quality.md, "Twenty-seventh
#: session": the funnel 1.78 -> 1.63 x the bound, the seven clutter maps 1.7 % sooner in sum.
LEADING = "fast, leading"
#: Share of half a robot's drift room it may lead or lag its cell by in the :data:`LEADING` attempt (0: no such
#: attempt).
LEAD_ROOM = 1.0
#: The factors of the flown durations at which the whole flight's QP is tried, in this order, until one has no
#: certified solution (the last certified one is flown). A try that fails runs to the QP backend's iteration cap
#: (0.5 s on the arena against 0.15-0.2 s for one solved): descending, one try fails. At a third of the budget
#: (the attempts' OPTIMISTIC_BUDGET) the refined arena's x0.98 was not solved.
RETIME_FACTORS = (0.98, 0.96, 0.94, 0.92, 0.90)


class Rejection(str):
    """Why a chunk's QP has no solution: the text (what :attr:`WindowRecord.failed` keeps), and ``status``, the QP
    backend's own status where it ended without a solution it did not prove infeasible
    (:class:`~solvers.errors.SolveFailedError`; None otherwise), which ``result.json``'s ``solve_failures`` counts.
    A ``str``, so that it reads as the reason did before; the count read the status back from the text with a regex.
    """

    status: str | None

    def __new__(cls, text: str, status: str | None = None) -> Rejection:
        self = super().__new__(cls, text)
        self.status = status
        return self


@dataclass
class WindowRecord:
    """One planning window: steps a..b planned, a..c flown.

    Attributes
    ----------
    attempt
        What was flown: ``"nominal"``, ``"previous"`` (the previous window's durations on
        the overlap), ``"slower xF"`` or ``"witness"``.
    failed
        Why the attempts before it were rejected.
    unsolved
        The QP backend's status for each attempt of ``failed`` it ended without a solution for, not proved
        infeasible (:class:`Rejection`'s ``status``), in order.
    rounds
        QP solves of the lazy constraint generation (over all attempts).
    active_pairs
        Relative safe corridors switched on in the accepted solution.
    refined
        The time refinement was accepted.
    creep
        The accepted solution keeps the robots that drift through short waits moving at
        :data:`CREEP_SPEED` or faster (an attempt of the bold or moderate profile).
    hold
        The accepted solution holds the robots that have arrived for good still at their cells
        (:func:`~mrfswarm.continuous.regions.arrival_holds`; tried with the creep rows, then without them).
    released
        The arrived robots not held where the holds failed (:meth:`RecedingHorizon._releases`).
    refine_error
        The NLP backend's error where it raised in the refinement (its first line; empty otherwise): the window
        keeps the best certified point it had evaluated, or its QP's durations.
    bisected
        Steps of :meth:`RecedingHorizon._bisect` kept: the window flies durations between ``attempt``'s and
        those of a faster attempt that failed.
    piece_steps
        Steps of each polynomial piece the window flies (all ones: one piece per step;
        :mod:`mrfswarm.continuous.merge_pieces`).
    cost
        Snap integral of the window's accepted solution (all robots).
    durations
        The accepted step durations of the whole window (seconds).
    """

    a: int
    c: int
    b: int
    attempt: str = ""
    failed: list[str] = field(default_factory=list)
    unsolved: list[str] = field(default_factory=list)
    rounds: int = 0
    active_pairs: int = 0
    refined: bool = False
    refine_error: str = ""
    creep: bool = False
    hold: bool = False
    released: list[int] = field(default_factory=list)
    bisected: int = 0
    cost: float = 0.0
    solve_s: float = 0.0
    durations: np.ndarray | None = None
    piece_steps: list[int] = field(default_factory=list)

    def note_unsolved(self, why: str) -> None:
        """Keep the QP backend's status in :attr:`unsolved` where ``why``, an attempt's reason just put in
        :attr:`failed`, is a :class:`Rejection` that carries one."""
        if isinstance(why, Rejection) and why.status is not None:
            self.unsolved.append(why.status)

    @property
    def pieces(self) -> int:
        """Polynomial pieces the window flies (per robot)."""
        return len(self.piece_steps)


@dataclass
class ContinuousPlan:
    """The smooth trajectories of every robot and what the continuous stage proved and measured.

    Attributes
    ----------
    trajectories
        One :class:`PiecewisePolynomial` of the plan's dimension (2 or 3) per robot, all on
        one time grid: the knots
        ``knot_times[piece_steps]``, one piece per step or, where ``smoothing.max_pieces``
        needed it, per several steps.
    knot_times
        (T + 1,) the time each discrete step is reached.
    piece_steps
        (P + 1,) the step at which each piece starts, and T.
    max_pieces
        ``smoothing.max_pieces`` (0: no limit).
    pieces_per_robot
        Each robot's number of pieces.
    regions, separations
        The safe regions and relative safe corridors the trajectories were planned in.
    windows
        One record per planning window.
    certificate
        The certificate of the whole flight.
    v_max, a_max, j_max
        Exact maxima over all robots of speed, acceleration and jerk.
    min_separation
        Exact smallest distance between two robots over the flight (metres), in the
        downwash-scaled metric :math:`\\|(p_i - p_k) \\odot s\\|`, ``s =
        geometry.downwash_scale(dim, downwash)`` (the metric the safety distance
        2 r is defined in: the plain distance in the plane or with ``downwash`` 1).
    min_clearance
        Smallest distance from a robot's centre to an occupied cell, sampled (metres; None
        without obstacles nearby).
    downwash
        The downwash factor c the separations were planned and measured with.
    sampled
        The optional dense sampled check (None unless ``smoothing.check_rate_hz`` > 0).
    timings
        Seconds per part: regions, smoothing, checking.
    retimed
        The factor a short flight's durations were re-timed by as a whole (``RETIME_FACTORS``), None if it was
        not.
    horizon
        Steps per planning window (``smoothing.horizon``, or more where :func:`braking_horizon` lengthened them).
    makespan_s, dim
        The flight's duration (s, the last knot) and its dimension (properties).

    :meth:`positions` gives every robot's position at given times; a robot's velocity and higher
    derivatives are ``trajectories[i].evaluate(t, derivative)``.
    """

    trajectories: list[PiecewisePolynomial]
    knot_times: np.ndarray
    regions: Regions
    separations: Separations
    windows: list[WindowRecord]
    certificate: Certificate
    v_max: float
    a_max: float
    j_max: float
    min_separation: float
    min_clearance: float | None
    sampled: SampledCheck | None = None
    timings: dict[str, float] = field(default_factory=dict)
    piece_steps: np.ndarray | None = None
    max_pieces: int = 0
    pieces_per_robot: list[int] = field(default_factory=list)
    downwash: float = 1.0
    retimed: float | None = None
    horizon: int = 0

    @property
    def min_separation_scaled(self) -> float:
        """:attr:`min_separation`, named for what it is (the downwash-scaled metric)."""
        return self.min_separation

    @property
    def dim(self) -> int:
        """2 or 3."""
        return self.trajectories[0].dim

    @property
    def makespan_s(self) -> float:
        return float(self.knot_times[-1])

    @property
    def pieces_fit(self) -> bool:
        """Every robot has at most ``max_pieces`` pieces (True without a limit)."""
        return self.max_pieces == 0 or max(self.pieces_per_robot, default=0) <= self.max_pieces

    def positions(self, times: np.ndarray | float) -> np.ndarray:
        """(S, N, dim) every robot's position at ``times`` (s) of shape (S,) ((N, dim) at one time given as a number;
        ``times.shape + (N, dim)`` for times of any shape); times outside the flight are clamped to it (before it:
        the starts, after it: where the robots rest).

        Raises
        ------
        ValueError
            A time that is not a finite number (NaN gave NaN positions without a word, a string NumPy's "could not
            convert string to float").
        """
        try:
            t = np.asarray(times, dtype=float)
        except (TypeError, ValueError):
            raise ValueError(f"positions: times must be numbers (s), got {times!r:.60}") from None
        if not np.all(np.isfinite(t)):
            raise ValueError(f"positions: times must be finite, got {times!r:.60}")
        # robots on the axis before the point's: times of shape (4, 3) gave (4, N, 3, dim), robots between them
        return np.stack([tr.evaluate(t) for tr in self.trajectories], axis=-2)


@dataclass
class _Solution:
    """A window's trajectories: knot derivatives (N, M+1, q, dim), bubbles (N, M, nb, dim), durations (M,)."""

    Y: np.ndarray
    B: np.ndarray
    durations: np.ndarray
    cost: float = 0.0
    gradient: np.ndarray | None = None  # d cost / d durations (M,), when asked for
    cps: list[np.ndarray] | None = None  # [P, V, A, J] control points, as _control_points gives them


@dataclass
class TimeAllocation:
    """The time refinement's NLP of one window (:meth:`RecedingHorizon.time_allocation`).

    Attributes
    ----------
    problem
        f(T) = J*(T) + weight sum(T) over the window's step durations T, with bounds.
    base
        The lazy rows (corridors, limits) active when it was built.
    weight
        ``time_weight`` x robots.
    solved
        Every evaluated point (``T.tobytes()``) and the window's solution there (None:
        the QP had none).
    rows
        The lazy rows each evaluated point needed.
    """

    problem: NLPProblem
    base: tuple[np.ndarray, np.ndarray]
    weight: float
    solved: dict[bytes, _Solution | None] = field(default_factory=dict)
    rows: dict[bytes, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)


def _cell_paths(paths: object, grid: OccupancyGrid) -> np.ndarray:
    """``paths`` as (T + 1, N, d) integer cells of ``grid`` (d = ``grid.ndim``, at least one configuration and one
    robot), or ScenarioError saying what is wrong. Paths in metres (``Result.discrete_paths_world()``) were floored
    to other cells without a word, NaN cast with a RuntimeWarning, (T + 1, N) paths ended in an IndexError inside
    the regions and no configuration at all in NumPy's "attempt to get argmax of an empty sequence" (a library
    tour)."""
    try:
        p = np.asarray(paths, dtype=float)
    except (TypeError, ValueError):
        raise ScenarioError(f"paths must be (T + 1, N, {grid.ndim}) grid cells, got {paths!r:.60}") from None
    if p.ndim != 3 or p.shape[-1] != grid.ndim or min(p.shape) < 1:
        raise ScenarioError(f"paths must have shape (T + 1, N, {grid.ndim}), one index per axis of the grid's "
                            f"{grid.ndim} axes: the cells of every robot at every step, got {p.shape}")
    bad = ~np.isfinite(p) | (p != np.round(p))
    if bad.any():
        t, i = (int(v) for v in np.argwhere(bad)[0][:2])
        raise ScenarioError(f"paths[{t}, {i}] = {p[t, i].tolist()}: paths are grid cells, whole numbers (metres? "
                            "cells are grid.world_to_cell(points))")
    return p.astype(np.int64)


class RecedingHorizon:
    """Smooths discrete paths window by window on one common time grid.

    Parameters
    ----------
    paths
        (T + 1, N, d) discrete paths in cells, d = 2 or 3 (the grid's).
    grid
        The occupancy grid.
    cfg
        The smoothing settings.
    radius
        Robot radius (metres); the safety distance is twice it.
    downwash
        The downwash factor c >= 1 (``scenario.downwash``): two robots are apart when their
        distance scaled by ``geometry.downwash_scale(d, c)`` (z divided by c) is at least
        the safety distance. It changes nothing in the plane.
    backend
        QP backend name for every solve (default ``cfg.backend``).
    qp_options
        Options of every QP solve (default :data:`QP_OPTIONS`).
    workers
        Processes that solve a window's independent chunks of robots at once (default:
        the machine's cores; used for swarms of ``PARALLEL_ROBOTS`` or more). The plan
        does not depend on it.

    Raises
    ------
    SolverNotFound
        An unknown or missing QP backend, or with ``cfg.time_refinement`` NLP backend
        (``cfg.nlp``).
    ConfigError
        ``cfg`` that is not a :class:`~mrfswarm.config.SmoothingConfig`.
    ScenarioError
        ``paths`` that are not (T + 1, N, d) whole numbers, T + 1 and N at least 1; a radius not in (0, half a
        cell); two robots closer than the safety distance in a step.
    UnsafeTrajectoryError
        A region closer than the robot radius to an obstacle (the discrete plan breaks its
        motion rule).
    """

    def __init__(self, paths: np.ndarray, grid: OccupancyGrid, cfg: SmoothingConfig, radius: float,
                 backend: str | None = None, qp_options: QPOptions | None = None, workers: int | None = None,
                 downwash: float = 1.0) -> None:
        t0 = time.perf_counter()
        if not isinstance(cfg, SmoothingConfig):  # a dict ended in "'dict' object has no attribute 'backend'"
            raise ConfigError(f"cfg must be a mrfswarm.config.SmoothingConfig (a Config's .smoothing), got "
                              f"{type(cfg).__name__}")
        self.paths = _cell_paths(paths, grid)
        self.dim = self.paths.shape[-1]
        self.downwash = float(downwash)
        self.scale = downwash_scale(self.dim, self.downwash)
        self.grid, self.cfg = grid, cfg
        self.backend = backend or cfg.backend
        solvers.qp.BACKENDS.get(self.backend)  # an unknown or missing backend fails now
        if cfg.time_refinement and cfg.refinement == "nlp":
            solvers.nlp.BACKENDS.get(cfg.nlp)  # and so does the refinement's NLP backend
        self.qp_options = qp_options or QP_OPTIONS
        #: the time refinement's NLP options: the config's [smoothing.nlp_options] over NLP_OPTIONS
        self.nlp_options = dataclasses.replace(NLP_OPTIONS, **cfg.nlp_options)
        budget = solvers.qp.BACKENDS.get(self.backend).capabilities.iteration_budget(self.qp_options.max_iter)
        self.optimistic_options = dataclasses.replace(self.qp_options,
                                                      max_iter=max(1, math.ceil(OPTIMISTIC_BUDGET * budget)))
        self.trial_options = dataclasses.replace(self.qp_options, max_iter=max(1, math.ceil(TRIAL_BUDGET * budget)))
        self.T, self.N = len(self.paths) - 1, self.paths.shape[1]
        self.horizon = cfg.horizon  # lengthened below where the windows' tails could not brake from the cruise
        self.merged_unit = 1.0  # the time unit of merged windows, a share of their steps' (MERGED_TIME_UNIT)
        self.radius = float(radius)
        self.distance = 2 * self.radius
        # room for the compressed export's rounding, where the cells leave it (a quarter of what a cell leaves
        # around a robot: the rest-to-rest witness keeps that much, so a window never lacks a feasible point)
        self.slack = export_slack(grid.resolution, self.radius)
        self.limits = (cfg.v_max, cfg.a_max, cfg.j_max)
        # the QP's limit rows keep EXPORT_LIMIT_SLACK free; the certificate checks the limits themselves
        v, acc, jerk = (lim * (1 - e) for lim, e in zip(self.limits, EXPORT_LIMIT_SLACK))
        self.row_limits = (v, acc, jerk)
        self.X = grid.cell_to_world(self.paths)
        self.index = ObstacleIndex(grid)
        self.regions = build_regions(self.paths, grid, self.radius, cfg.region_growth, self.index, self.scale)
        self.held = arrival_holds(self.paths, HOLD_SETTLE)
        clearance = region_clearance(self.regions, grid, 2 * self.radius)
        if self.T and clearance.min() < self.radius:
            j, i = np.unravel_index(int(np.argmin(clearance)), clearance.shape)
            raise UnsafeTrajectoryError(f"robot {i}'s safe region in step {j} comes {clearance[j, i]:.3f} m from "
                                        f"an obstacle (radius {self.radius:g} m): the discrete move is unsafe")
        self.seps = separations(self.X, self.regions, self.distance, self.scale)
        self.profiles: list[SwarmProfile] = []  # one per PROFILES entry
        #: Hopeful attempts with creep rows or holds so far: [no solution without them, solved with them]
        #: (:data:`PLAIN_FAIL_WEIGHT`).
        self.plain_odds = [0, 0]
        self.creep = np.zeros((self.T, self.N, self.dim))  # (T, N, d) CREEP_SPEED along the way of drifting waits
        self._exit = np.full((self.T, self.N), self.T)
        if cfg.speed is None and self.T:
            drift = drift_room(grid.resolution, self.radius)
            # the speed the profiles are set for (their cruise, their acceleration over a speed change of it, and
            # their braking): v_max, or less where no robot's way is long enough to reach it (time_grid.
            # reachable_speed). Set for v_max, a short flight at a loose v_max got an acceleration the jerk limit
            # does not allow over the speeds it reaches (see motion_acceleration), every profile failed, and it flew
            # later than at a tighter v_max: 4 robots on 14 x 10 m, 9.0 s at v_max 20 or 50 against 6.1 at 5; now
            # 6.6 s from v_max 6 to 50 (their ways reach 5.2 m/s; capping the cruise and acceleration alone, not the
            # braking: 6.0 s from 6 to 20, 6.6 at 50). Every flight-quality map reaches v_max: the same flights.
            longest = float(np.linalg.norm(np.diff(self.X, axis=0), axis=-1).sum(axis=0).max())  # metres
            change = reachable_speed(longest, cfg.v_max, cfg.a_max, cfg.j_max)
            reach = (min(self.limits[0], change), *self.limits[1:])
            self.profiles = [motion_profile(self.paths, grid.resolution, cruise * change,
                                            motion_acceleration(change, cfg.a_max, cfg.j_max, acc),
                                            drift if name != "cautious" else 0.0, reach)
                             for name, cruise, acc in PROFILES]
            self.nominal = self.profiles[[name for name, _, _ in PROFILES].index("nominal")].durations
            moves = np.diff(self.X, axis=0)
            _, way, _ = drift_waits(moves, CREEP_WAITS)
            if drift > 0:
                self.creep = CREEP_SPEED * way
            self._exit = next_moves(moves)  # a run's rows go in a window that holds its way out
            self.horizon = braking_horizon(cfg, change, grid.resolution)
            if braking_steps(cfg, change, grid.resolution) > FINE_BRAKING_STEPS:
                self.merged_unit = MERGED_TIME_UNIT
            if self.horizon > cfg.horizon:
                log.info("windows of %d steps instead of smoothing.horizon = %d: their unflown steps brake from %.2f "
                         "m/s on %g m cells", self.horizon, cfg.horizon, change, grid.resolution)
        elif cfg.speed is None:
            self.nominal = np.zeros(0)
        else:
            self.nominal = nominal_durations(self.paths, grid.resolution, cfg.speed, NOMINAL_ACCELERATION * cfg.a_max)
        self.E = max(1, round(cfg.execution * self.horizon))
        #: The fast profile with the robots leading or lagging their cells at the flight's inner knots (None
        #: without profiles, drift room or :data:`LEAD_ROOM`, and in a refined run: refining from it as well was
        #: mixed, the corridor 19.49 -> 19.55 s, halls50 28.99 -> 29.55, clutter40 43.16 -> 43.31, aisles30 31.21 ->
        #: 30.78, the funnel 23.91 -> 23.72, forest and rooms 0.4 % sooner, the same in sum).
        self.leading: SwarmProfile | None = None
        room = drift_room(grid.resolution, self.radius)
        if self.profiles and LEAD_ROOM > 0 and not cfg.time_refinement and room > 0:
            _, cruise, acc = PROFILES[0]  # the fast profile's
            self.leading = motion_profile(self.paths, grid.resolution, cruise * change,
                                          motion_acceleration(change, cfg.a_max, cfg.j_max, acc), room, reach,
                                          lead=LEAD_ROOM * room / 2)
        if cfg.seam == "continuous" and self.E >= self.horizon and self.T > self.E:
            # every window ends at rest at its last step: flown to its end, the flight stops there (on a 14 x 10 m
            # map of 4 robots: 8.3 s by default, 11.5 s at execution 1.0, 26.4 s at horizon 1)
            log.warning("smoothing.execution = %g of smoothing.horizon = %d flies every window to its end, where "
                        "the robots are planned at rest: the flight stops every %d steps (flying less than the whole "
                        "window lets the next one take over while they move)", cfg.execution, self.horizon, self.E)
        self.witness = np.maximum(self.nominal, witness_durations(
            self.paths, grid.resolution, self.row_limits, cfg.degree, cfg.derivative, MARGIN))
        # the reference: each step's longest move (at least a cell) at REFERENCE_SPEED, whatever the limits
        moves = np.linalg.norm(np.diff(self.X, axis=0), axis=-1)
        reference = np.maximum(moves.max(axis=1, initial=0.0), grid.resolution) / REFERENCE_SPEED
        slow = self.witness / np.maximum(reference, 1e-12)
        if self.T and slow.max() > MAX_SLOWDOWN:
            raise UnsafeTrajectoryError(
                f"no timing meets v_max = {cfg.v_max:g} m/s, a_max = {cfg.a_max:g} m/s^2 and j_max = {cfg.j_max:g} m/s^3 "
                f"within {MAX_SLOWDOWN:g} times the step durations at {REFERENCE_SPEED:g} m/s (step "
                f"{int(np.argmax(slow))} would need {self.witness.max():.3g} s)")
        # rows switched on by lazy constraint generation (grow over the run)
        self.active = np.zeros(len(self.seps), dtype=bool)
        # per face of the limit polytope and quarter of a piece (LIMIT_PARTS): only the faces a solution crosses, on
        # the quarters where it does. In space, 13 faces per control point would make the limit rows most of a
        # window's QP (190 000 rows of 200 000 for 40 robots in a lattice); in the plane the octagon's 4 faces came
        # on together, on all quarters, until 2026-11-27: the 300-robot crossing's window QPs took 111 s, per
        # face 37 s; the open field of 50 planned in 20.3 s, per face and quarter 5.6 s (the same flights)
        self.limit_rows = np.zeros((self.T, self.N, 3, len(limit_polytope(self.dim)[0]), LIMIT_PARTS), dtype=bool)
        self.workers = usable_workers(max(1, workers if workers is not None else (os.cpu_count() or 1)))
        self._pool: ProcessPoolExecutor | None = None
        # robots of the chunk whose QP failed last: solved first, so a failing attempt costs one chunk
        self._hard = np.zeros(self.N, dtype=bool)
        #: After a window's time refinement kept a point: the window's solution before it and the rows
        #: (``active``, ``limit_rows``, ``_hard``) that went with it (None otherwise); see ``_run``.
        self.unrefined: tuple[_Solution, tuple[np.ndarray, np.ndarray, np.ndarray]] | None = None
        self._no_multipliers = False  # said once: the QP backend gives none, the refinement has no gradient
        self.regions_s = time.perf_counter() - t0
        self._check_s = 0.0

    # ------------------------------------------------------------------ windows
    def windows(self) -> list[tuple[int, int, int]]:
        """(a, c, b) of every window: steps a..b planned, a..c flown."""
        out, a = [], 0
        while a < self.T:
            c = min(a + self.E, self.T)
            b = c if self.cfg.seam == "rest" else min(a + self.horizon, self.T)
            out.append((a, c, b))
            a = c
        return out

    def _spec(self, a: int, b: int, robots: np.ndarray, start: np.ndarray, pairs: np.ndarray,
              merged: np.ndarray | None = None, creep: int | None = None, hold: bool = False,
              release: np.ndarray | None = None) -> WindowSpec:
        """The problem data of ``robots`` over steps a..b with the corridors ``pairs`` (indices into the plan's),
        the knots ``merged`` inside pieces that span several steps and, with ``creep`` = c (the window flies
        a..c), the drifting waits' rows: in the flown steps, and in the others of runs whose way out is in the
        window (the window ends at rest at b); with ``hold``, the arrived robots held still
        (:meth:`_held_regions`) but those of ``release``."""
        cfg = self.cfg
        local = np.full(self.N, -1)
        local[robots] = np.arange(len(robots))
        seps = self.seps.select(pairs)
        return WindowSpec(
            degree=cfg.degree, derivative=cfg.derivative, regions=(self._held_regions(a, b, robots, start, merged, release) if hold
                                                                     else self.regions.window(a, b, robots)),
            pair_step=seps.step - a, pair_first=local[seps.first], pair_second=local[seps.second],
            pair_normal=seps.normal, distance=self.distance, start=start[robots], end=self.X[b, robots],
            origin=self.X[a, robots], limits=self.row_limits,
            time_scale=float(np.exp(np.log(self.nominal[a:b]).mean())) * (1.0 if merged is None else self.merged_unit),
            margin=MARGIN if merged is None else MERGED_MARGIN, slack=self.slack, limit_mask=self.limit_rows[a:b, robots],
            merged=merged, unit_merge_rows=merged is not None and self.merged_unit != 1.0,
            creep=None if creep is None else self._creep_rows(a, b, creep)[:, robots])

    def _held_regions(self, a: int, b: int, robots: np.ndarray, start: np.ndarray,
                      merged: np.ndarray | None, release: np.ndarray | None = None) -> Regions:
        """The regions of ``robots`` over steps a..b, the arrived robots held still at their cells
        (:func:`~mrfswarm.continuous.regions.arrival_holds`) where the window can fly it.

        A held robot is pinned at rest at its cell from the start of its first held step on
        (that step's box is the hold; staying costs no snap, so it stays): not in the
        window's first piece (whose start state is given: a pin there would ask it to be
        the centre exactly), not in a piece that also spans unheld steps (its one
        polynomial would have to be constant), not in the window's last step (the window
        ends at rest at the cell anyway), and a robot that does not start the window at rest
        at its cell gets :data:`HOLD_SETTLE` steps more to brake. Pinning every held step
        repeated the knots' shared states in equality rows, and piqp ran out of iterations.
        The robots of ``release`` (N,) bool are not held (:meth:`_releases`).
        """
        regions = self.regions.window(a, b, robots)
        held = self.held[a:b, robots].copy()
        if release is not None:
            held[:, release[robots]] = False
        if not held.any():
            return regions
        M = b - a
        piece = np.arange(M) if merged is None else np.concatenate([[0], np.cumsum(~np.asarray(merged, dtype=bool))])
        still = self._still(start, a)[robots]
        held[:HOLD_SETTLE, ~still] = False
        held[piece == 0] = False
        for k in np.unique(piece):
            rows = piece == k
            mixed = held[rows].any(axis=0) & ~held[rows].all(axis=0)
            held[np.ix_(rows, mixed)] = False
        first = np.argmax(held, axis=0)
        pin = np.zeros_like(held)
        cols = np.flatnonzero(held.any(axis=0) & (first < M - 1))
        pin[first[cols], cols] = True
        return hold_regions(regions, pin, self.X[a:b, robots], self.slack + HOLD_ROOM)

    def _still(self, start: np.ndarray, a: int) -> np.ndarray:
        """(N,) bool: the robots whose ``start`` state (N, q, d) at step a is at rest at their cells."""
        return (np.abs(start[:, 0] - self.X[a]).max(axis=-1) <= HOLD_ROOM) & (np.abs(start[:, 1:]).max(axis=(1, 2)) <= 1e-6)

    def _releases(self, sol: _Solution, a: int, b: int, start: np.ndarray) -> list[np.ndarray]:
        """The robots to release from their holds where the holds of steps a..b failed, (N,) bool each, fewest
        first: those that ``sol`` (the window's solution without the holds) brings within :data:`RELEASE_GAP` of
        a corridor's plane with another robot in a held step, then those and every robot that does not start
        the window at rest at its cell. Neither if it releases none or all of the held robots.

        A robot held still at its cell cannot make way for a neighbour that swings past it (a reversal next to
        it, at the fast durations), and one that starts the window away from its cell may not brake there in
        the window's first piece: the holds of the whole window fail, and every arrived robot drifts.
        """
        held = self.held[a:b]
        some = held.any(axis=0)
        if sol.cps is None or not some.any():
            return []
        cand = np.flatnonzero((self.seps.step >= a) & (self.seps.step < b) & self.active)
        seps = self.seps.select(cand)
        j = seps.step - a
        gap = np.einsum("pmk,pk->pm", sol.cps[0][seps.first, j] - sol.cps[0][seps.second, j], seps.normal).min(axis=1)
        tight = gap < self.distance + self.slack + RELEASE_GAP
        release = np.zeros(self.N, dtype=bool)
        release[seps.first[tight & held[j, seps.first]]] = True
        release[seps.second[tight & held[j, seps.second]]] = True
        still = self._still(start, a)
        out: list[np.ndarray] = []
        for mask in (release, release | ~still):
            if mask[some].any() and not mask[some].all() and not any(np.array_equal(mask, m) for m in out):
                out.append(mask)
        return out

    def _creep_rows(self, a: int, b: int, c: int) -> np.ndarray:
        """(b - a, N, d) the creep rows of a window that plans a..b and flies a..c: in the flown steps, and in the
        others of runs whose way out is in the window (it ends at rest at b)."""
        return self.creep[a:b] * ((self._exit[a:b] < b) | (np.arange(a, b) < c)[:, None])[..., None]

    def _solve(self, a: int, b: int, start: np.ndarray, durations: np.ndarray, rec: WindowRecord,
               gradient: bool = False, merged: np.ndarray | None = None,
               optimistic: bool = False, creep: int | None = None,
               limits: bool = True, hold: bool = False,
               release: np.ndarray | None = None, trial: bool = False) -> tuple[_Solution | None, str]:
        """The window's QP at ``durations``, its corridor and limit rows added lazily (without ``limits``, none of
        the limit rows: the caller clears them).

        A round solves the robots whose constraint set changed (robots linked by the
        active corridors are solved together, so independent groups decouple); the
        corridors and limit polygons that the solution violates are then switched on, and
        the next round re-solves the groups they touch. When nothing is violated the
        solution is optimal for the whole window problem (it solves a relaxation and is
        feasible). Sets grow monotonically over the run, so later windows start with the
        rows found active before.
        """
        q, pm, M = self.cfg.derivative, piece_maps(self.cfg.degree, self.cfg.derivative), b - a
        Y = np.zeros((self.N, M + 1, q, self.dim))
        B = np.zeros((self.N, M, pm.nz - 2 * q, self.dim))
        cost = np.zeros(self.N)
        grad = np.zeros((self.N, M)) if gradient else None
        cps = [np.zeros((self.N, M, pm.rows[r], self.dim)) for r in range(4)]
        cand = np.flatnonzero((self.seps.step >= a) & (self.seps.step < b))
        seps = self.seps.select(cand)
        todo = np.ones(self.N, dtype=bool)
        for rnd in range(MAX_ROUNDS + 1):
            if rnd == MAX_ROUNDS:  # never happens in practice; every row on ends the loop
                self.active[cand] = True
                self.limit_rows[a:b] = True
                todo[:] = True
            groups = interaction_groups(self.N, seps.select(self.active[cand] & todo[seps.first] & todo[seps.second]))
            chunks = pack_groups([g for g in groups if todo[g[0]]], chunk_size(int(todo.sum())))
            specs = []
            for robots in chunks:
                mine = np.zeros(self.N, dtype=bool)
                mine[robots] = True
                specs.append(self._spec(a, b, robots, start, cand[self.active[cand] & mine[seps.first]], merged, creep,
                                        hold, release))
            results, why = self._solve_chunks(chunks, specs, durations, gradient, optimistic, trial)
            rec.rounds += 1
            if why:
                return None, why
            for robots, out in zip(chunks, results):
                Y[robots], B[robots], cost[robots], g = out
                if grad is not None:
                    if g is None:  # the backend gives no multipliers: a solution without the gradient
                        grad = None
                        if not self._no_multipliers:
                            self._no_multipliers = True
                            log.warning("QP backend %s gives no multipliers: the time refinement has no gradient "
                                        "and refines no window (its attempts still keep the first step the window "
                                        "before planned and bisect between rungs, so the flight is not the "
                                        "default's either)",
                                        self.backend)
                    else:
                        grad[robots] = g
            robots = np.flatnonzero(todo)
            for r, part in enumerate(self._control_points(Y[robots], B[robots], durations)):
                cps[r][robots] = part
            # corridors (of the robots just solved): n . (P_i - P_k) >= d (+ half the margin: what the solver reaches)
            look = todo[seps.first] | todo[seps.second]
            gap = np.full(len(cand), np.inf)
            gap[look] = np.einsum("pmk,pk->pm", cps[0][seps.first[look], seps.step[look] - a]
                                  - cps[0][seps.second[look], seps.step[look] - a], seps.normal[look]).min(axis=1)
            new_pairs = (gap < self.distance + self.slack + MARGIN / 2) & ~self.active[cand]
            faces, inner = limit_polytope(self.dim)
            new_limits = np.zeros((M, self.N, 3, len(faces), LIMIT_PARTS), dtype=bool)
            for r, lim in zip((1, 2, 3), self.row_limits):
                n, _, K, d = cps[r][robots].shape  # K: the control points of LIMIT_PARTS parts, part after part
                parts = np.abs(cps[r][robots].reshape(n, M, LIMIT_PARTS, K // LIMIT_PARTS, d) @ faces.T).max(axis=3)
                over = parts > lim * inner * (1 - MARGIN / 2)  # (n, M, parts, F)
                new_limits[:, robots, r - 1] = over.transpose(1, 0, 3, 2) & ~self.limit_rows[a:b, robots, r - 1]
            if not limits:
                new_limits[:] = False
            if not new_pairs.any() and not new_limits.any():
                rec.active_pairs = int(self.active[cand].sum())
                return _Solution(Y, B, durations, float(cost.sum()),
                                 None if grad is None else grad.sum(axis=0), cps), ""
            self.active[cand[new_pairs]] = True
            self.limit_rows[a:b] |= new_limits
            touched = np.zeros(self.N, dtype=bool)
            touched[seps.first[new_pairs]] = touched[seps.second[new_pairs]] = True
            touched |= new_limits.any(axis=(0, 2, 3, 4))
            todo = np.zeros(self.N, dtype=bool)
            for g in interaction_groups(self.N, seps.select(self.active[cand])):
                if touched[g].any():
                    todo[g] = True
        return None, "constraint generation did not settle"  # unreachable: the last round has every row

    def _stretched(self, a: int, c: int, b: int, start: np.ndarray, bold: np.ndarray, cautious: np.ndarray,
                   rec: WindowRecord, merged: np.ndarray | None, creep: int | None,
                   hold: bool = False) -> list[tuple[str, np.ndarray]]:
        r"""The attempts between the moderate and the cautious profile: the ``bold`` durations stretched step by step.

        The window's solution at the bold durations without any limit row tells which steps are too short for the
        limits, and by how much: stretching step j by :math:`s_j = \max(1, \max_{i, r} (p_{ijr} / l_r)^{1/r})`,
        with :math:`p_{ijr}` the largest r-th derivative control point of robot i in step j (on the limit
        polytope's faces) and :math:`l_r` its limit, flies that same solution's pieces within the limits (the r-th
        derivative of a piece flown s times slower is s^r times smaller). Continuity across steps stretched
        differently changes the pieces, so the QP decides. Returns (name, durations) for every power of
        :data:`STRETCH_POWERS` whose flown steps (a..c) last less than the ``cautious`` ones; none if the window
        has no solution at the bold durations even without limit rows.
        """
        if not STRETCH_POWERS:
            return []
        saved = self.limit_rows[a:b].copy()
        self.limit_rows[a:b] = False
        try:
            sol, why = self._solve(a, b, start, bold, rec, merged=merged, optimistic=True, creep=creep, limits=False,
                                   hold=hold)
        finally:
            self.limit_rows[a:b] = saved
        if sol is None or sol.cps is None:
            rec.failed.append(f"stretch: {why}")
            rec.note_unsolved(why)
            return []
        faces, inner = limit_polytope(self.dim)
        stretch = np.ones(len(bold))
        for r, lim in zip(LIMIT_ORDERS, self.row_limits):
            peak = np.abs(sol.cps[r] @ faces.T).max(axis=(0, 2, 3)) / (lim * inner * (1 - MARGIN))
            stretch = np.maximum(stretch, peak ** (1.0 / r))
        out = []
        for power in STRETCH_POWERS:
            durations = bold * stretch**power
            if durations[:c - a].sum() < cautious[:c - a].sum():
                out.append((f"stretched^{power:g}", durations))
        return out

    def _solve_chunks(self, chunks: list[np.ndarray], specs: list[WindowSpec], durations: np.ndarray,
                      gradient: bool, optimistic: bool = False, trial: bool = False) -> tuple[list, str]:
        """:func:`solve_window` of every chunk, the chunks holding robots that failed last time first, until one
        fails.

        A window's attempts share their durations across the swarm, so one chunk that cannot
        meet them fails the attempt: when those chunks fail again, the others are not solved, and
        the chunks not yet started when one fails are not solved either (:meth:`_map`).
        The solutions, and the attempt chosen, are the same as solving all chunks at once; only
        a failing attempt is cheaper. Returns the chunks' solutions (None where not solved) and "" or, when a chunk
        failed, why (and solutions that must not be used).
        """
        options = self.trial_options if trial else self.optimistic_options if optimistic else self.qp_options
        args = [(spec, durations, self.backend, options, gradient) for spec in specs]
        first = [k for k, robots in enumerate(chunks) if self._hard[robots].any()]
        rest = [k for k in range(len(chunks)) if k not in set(first)]
        results: list = [None] * len(chunks)
        for part in ([first, rest] if first and rest else [first + rest]):
            for k, out in zip(part, self._map(solve_window, [args[k] for k in part])):
                results[k] = out
            if any(isinstance(results[k], str) for k in part):
                break
        failed = [k for k in first + rest if isinstance(results[k], str)]
        if failed:
            self._hard[:] = False
            self._hard[chunks[failed[0]]] = True
            why = results[failed[0]]
            return results, Rejection(f"{len(chunks[failed[0]])} robots: {why}",
                                      why.status if isinstance(why, Rejection) else None)
        return results, ""

    def _map(self, fn: Callable, args: list[tuple]) -> list:
        """``fn(*a)`` for every ``a`` in order until one returns a string (why it failed): in the worker processes
        when there are several and workers. The results, None for those not run after a failure.

        In the workers every call is queued at once, and those not yet started when a failure comes back are
        cancelled (a started one runs to its end). Before, every chunk of a part was solved: of clutter40's
        refined trial points, a third of the failing rounds had solved every chunk. Against that
        (flight_quality.py --cases clutter40 --variants default,refined --baseline 79e4a7b --repeat 3, 2026-11-29):
        the same flights, refined planning 19.75 / 18.57 / 18.45 -> 17.49 / 17.99 / 18.30 s, the default's
        6.69 / 5.99 / 5.92 -> 6.10 / 6.13 / 7.22 (noise); the refinement over the default 3.10 -> 2.87 x. Queuing
        the hard chunks with the rest instead of alone first was no faster (a started chunk runs on after its
        attempt failed, and holds a worker from the next attempt).
        """
        out: list = [None] * len(args)
        if self._pool is None or len(args) < 2:
            for k, a in enumerate(args):
                out[k] = fn(*a)
                if isinstance(out[k], str):
                    break
            return out
        futures = {self._pool.submit(fn, *a): k for k, a in enumerate(args)}
        try:
            for done in as_completed(futures):
                out[futures[done]] = done.result()
                if isinstance(out[futures[done]], str):
                    break
        finally:  # after a failure, and on the way out of an interrupt as the pool's own map does
            for f in futures:
                f.cancel()
        return out

    def _control_points(self, Y: np.ndarray, B: np.ndarray, durations: np.ndarray) -> list[np.ndarray]:
        """[P, V, A, J] control points (N, M, K_r, dim) of knot derivatives ``Y`` and bubbles ``B``."""
        pm = piece_maps(self.cfg.degree, self.cfg.derivative)
        z = np.concatenate([Y[:, :-1], Y[:, 1:], B], axis=2)  # (N, M, nz, dim)
        scale = durations[:, None] ** pm.rpow[None, :]
        c = pm.E @ (z * scale[None, :, :, None])  # (K, nz) @ (N, M, nz, dim): one product per piece
        ck = np.moveaxis(c, 2, 0)  # coefficient first: each map below is one matrix product over every piece
        T = durations[None, :, None, None]
        return [np.moveaxis(map_coefficients(control_point_matrix(c.shape[2] - 1, r, 1 if r == 0 else LIMIT_PARTS), ck),
                            0, 2) / T**r for r in range(4)]

    def _certify(self, sol: _Solution, a: int) -> Certificate:
        tic = time.perf_counter()
        # the solve's control points of this very Y, B (every robot's were recomputed after its last QP)
        cps = sol.cps if sol.cps is not None else self._control_points(sol.Y, sol.B, sol.durations)
        out = certify_pieces(cps, self.regions.window(a, a + len(sol.durations)), self.distance, self.limits,
                             self.scale)
        self._check_s += time.perf_counter() - tic
        return out

    def _witness(self, a: int, b: int, durations: np.ndarray, prev: tuple | None) -> _Solution:
        """Every robot's discrete move rest to rest, after the previous window's plan where it reaches."""
        q, pm = self.cfg.derivative, piece_maps(self.cfg.degree, self.cfg.derivative)
        M = b - a
        Y = np.zeros((self.N, M + 1, q, self.dim))
        Y[:, :, 0] = self.X[a:b + 1].transpose(1, 0, 2)
        B = np.zeros((self.N, M, pm.nz - 2 * q, self.dim))
        if prev is not None:
            pa, pb, psol = prev
            Y[:, :pb - a + 1] = psol.Y[:, a - pa:]
            B[:, :pb - a] = psol.B[:, a - pa:]
        return _Solution(Y, B, durations)

    def _profile_attempts(self, a: int, c: int, b: int) -> list[tuple[str, np.ndarray]]:
        """The durations of steps a..b (flying a..c) a window tries first, fastest first: the profiles', or the
        nominal ones without profiles.

        The time refinement skipped the moderate profile until 2026-11-28; since the plans of ``mrf.contested =
        "auto"`` the refined open field flew later than its default without it (29.29 s against 28.98, its first
        window the bold durations stretched instead of the moderate profile). With it, refined: the open field
        28.93 s, clutter40 44.74 -> 44.08, aisles30 32.44 -> 32.25, the trap 25.18 -> 24.87, columns3d 15.65 ->
        15.61, the forest, rooms, corridor, doorway, arena, field3d and window3d the same."""
        nominal = self.nominal[a:b]
        if not self.profiles:
            return [("nominal", nominal)]
        # the window ends at rest at step b: its last steps brake to it
        attempts = [(name, np.maximum(p.durations[a:b], p.window(a, b))) for (name, _, _), p in
                    zip(PROFILES, self.profiles)]
        # the fast profile flies the flown steps only: the tail, planned and not flown, brakes as the bold one
        names = [name for name, _ in attempts]
        if "fast" in names:
            fast, bold = attempts[names.index("fast")][1], attempts[names.index("nominal")][1]
            attempts[names.index("fast")] = ("fast", np.concatenate([fast[:c - a], bold[c - a:]]))
        # the slower attempts start from the cautious profile
        attempts[-1] = (attempts[-1][0], np.maximum(attempts[-1][1], nominal))
        if "fast" in names:  # the fast attempt a little slower (the last window's: braking longer)
            fast, bold = attempts[names.index("fast")][1], attempts[names.index("nominal")][1]
            if b == self.T:
                longer = [(_braking(f), np.concatenate([fast[:-1], fast[-1:] * f])) for f in FINAL_BRAKING]
            else:
                longer = [(_slower(f), np.concatenate([fast[:c - a] * f, bold[c - a:]])) for f in FAST_SLOWER]
            attempts[1:1] = [(name, d) for name, d in longer if d[:c - a].sum() < bold[:c - a].sum()]
            if a == 0:
                attempts = self._jerk_start(attempts, c, fast, bold)
            if self.leading is not None:
                lead = np.maximum(self.leading.durations[a:b], self.leading.window(a, b))
                lead = np.concatenate([lead[:c - a], bold[c - a:]])
                if lead[:c - a].sum() < fast[:c - a].sum() - SAME_LENGTH:
                    attempts.insert(0, (LEADING, lead))
        return attempts

    def _jerk_start(self, attempts: list[tuple[str, np.ndarray]], c: int, fast: np.ndarray,
                    bold: np.ndarray) -> list[tuple[str, np.ndarray]]:
        """``attempts`` of the flight's first window (steps 0..b, flying 0..c) with the jerk-limited start
        (:data:`JERK_START`) before the first attempt after the fast one whose flown steps last longer."""
        ell = self.profiles[[name for name, _, _ in PROFILES].index("fast")].ell[:c]
        floor = np.diff(np.concatenate([[0.0], rest_times(np.cumsum(ell), *self.limits)]))
        start = np.concatenate([np.maximum(fast[:c], floor) * JERK_START, bold[c:]])
        flown = start[:c].sum()
        at = next((k for k, (_, d) in enumerate(attempts) if k and d[:c].sum() > flown), None)
        if at is None:
            return attempts
        return [*attempts[:at], (JERK_START_NAME, start), *attempts[at:]]

    @staticmethod
    def _follow(attempts: list[tuple[str, np.ndarray]], previous: np.ndarray) -> list[tuple[str, np.ndarray]]:
        """The attempts with their first step as the window before planned it (``previous``: its durations).

        The window starts in the state the last one left (speed, acceleration), which pins its first step from
        both sides (:mod:`~mrfswarm.continuous.duration_scaling`). After a refined window the profiles' first
        step seldom fits: on aisles30, 5 of 14 windows fell back to the previous window's durations (its braking
        tail) after 6 to 10 failed attempts. Every attempt with the planned first step, refined
        (flight_quality.py --variants refined --baseline 664a455 --baseline-variants refined, one run): planning
        forest 2.8 -> 1.8 s, aisles30 10.4 -> 6.2, clutter40 28.7 -> 23.1, open field 13.5 -> 12.8; flights
        forest 24.08 -> 23.91 s, clutter40 48.29 -> 47.56 (0.07 -> 0.03 stops per robot), aisles30
        35.12 -> 34.97, arena 6.15 -> 5.92, but corridor 19.61 -> 19.80, doorway 11.43 -> 11.48, rooms
        24.80 -> 24.97, trap 25.49 -> 25.71, open field 33.71 -> 33.87. Without the refinement the profiles
        follow each other, and holding the step in every attempt flew aisles30 39.71 -> 40.36 s (clutter40
        53.45 -> 52.73): the default tries the fast attempt with the planned first step as one more attempt,
        before the first attempt whose flown steps last longer (:data:`FOLLOWED`). Measured (flight_quality.py
        --variants default --baseline 47cc546, one run): clutter40 53.45 -> 52.50 s, aisles30 39.71 -> 39.55,
        open field 34.58 -> 34.48, trap 25.99 -> 25.90, arena 6.20 -> 6.18, corridor, doorway, forest and
        rooms the same flights; 200 robots in clutter 178.3 -> 167.5 s (1.43 -> 1.34 stops per robot), the
        300-robot crossing 67.39 -> 67.41 s. Both only with the profiles: with the durations of a given
        ``speed`` the corridor refined flew 20.75 -> 20.99 s following the first step.
        """
        return [(name, np.concatenate([previous[:1], d[1:]])) for name, d in attempts]

    def _plan_window(self, a: int, c: int, b: int, start: np.ndarray, prev: tuple | None,
                     pieces: int | None = None) -> tuple[_Solution, WindowRecord]:
        """Plan steps a..b (fly a..c) in ``pieces`` polynomial pieces over a..c (default: one per step).

        Every duration of the ladder is tried with the pieces asked for; if none is
        certified, with twice as many, and so on up to one piece per step, whose last
        resort is the witness (:mod:`mrfswarm.continuous.merge_pieces`).
        """
        rec = WindowRecord(a=a, c=c, b=b)
        tic = time.perf_counter()
        slow = self.witness[a:b]
        attempts = self._profile_attempts(a, c, b)
        nominal = attempts[-1][1]
        # the profiles before the cautious one fail often (the bold one in most windows of clutter): a smaller
        # iteration budget (OPTIMISTIC_BUDGET) lets them fail sooner
        optimistic = len(attempts) - 1 if self.profiles else 0
        # the attempts that drift through waits: every profile but the cautious one, and the stretched durations
        drifting = ({name for name, _, _ in PROFILES[:-1]} | {f"stretched^{p:g}" for p in STRETCH_POWERS}
                    | {_braking(f) for f in FINAL_BRAKING} | {_slower(f) for f in FAST_SLOWER} | {JERK_START_NAME, LEADING})
        has_creep = bool(self._creep_rows(a, b, c).any())
        has_hold = bool(self.held[a:b].any())
        overlap, base = 0, nominal
        if prev is not None:
            pa, pb, psol = prev
            overlap = pb - a
            base = np.concatenate([psol.durations[a - pa:], nominal[overlap:]])
            if self.cfg.time_refinement and self.profiles:
                attempts = self._follow(attempts, base)
            elif self.profiles:
                # the fast attempt (and the leading one) with that first step too, before the first attempt whose
                # flown steps last longer
                for first in [n for n, _ in attempts[:2] if n in (LEADING, "fast")][::-1]:
                    if dict(attempts)[first][0] == base[0]:
                        continue
                    name, durations = self._follow([(first, dict(attempts)[first])], base)[0]
                    k = 1
                    while k < len(attempts) - 1 and attempts[k][1][:c - a].sum() <= durations[:c - a].sum():
                        k += 1
                    attempts.insert(k, (name + FOLLOWED, durations))
                    optimistic += 1
                    drifting = drifting | {name + FOLLOWED}
            attempts.append(("previous", base))
        # slow the new steps down until every one lasts its witness duration
        target = np.maximum(slow[overlap:], nominal[overlap:])
        factor = 1.0
        while np.any(base[overlap:] * factor < target):
            factor *= SLOWDOWN
            attempts.append((f"slower x{factor:.3g}",
                             np.concatenate([base[:overlap], np.minimum(base[overlap:] * factor, target)])))
        chosen, merged, flown = None, None, c - a
        for p in _piece_options(flown if pieces is None else pieces, flown):
            missed: list[np.ndarray] = []  # the attempts without a certified solution at these pieces
            sizes = block_sizes(flown, p)
            merged = merged_knots(sizes, b - a) if p < flown else None
            label = f"{p} pieces, " if p < flown else ""
            tries = list(attempts)
            k = -1
            while k + 1 < len(tries):
                k += 1
                name, durations = tries[k]
                if name == PROFILES[-1][0] and len(tries) == len(attempts):
                    # the faster profiles failed: the bold durations stretched where the limits ask, if sooner
                    tries[k:k] = self._stretched(a, c, b, start, dict(attempts)["nominal"], durations, rec, merged,
                                                 c if has_creep else None, has_hold)
                    name, durations = tries[k]
                # a drifting profile with the creep rows and the arrived robots held, then (where they make it
                # fail) with the holds alone, then without both: the holds alone flew two of seven clutter40-type
                # maps with fewer stops (0.28 -> 0.17, 0.17 -> 0.15 per robot), the rest of the flight-quality
                # maps as before
                softs = [(has_creep, has_hold)] if name in drifting and (has_creep or has_hold) else []
                if softs and has_creep and has_hold:
                    softs.append((False, True))
                if name == "previous" and has_hold:
                    # the previous window's durations (where the profiles failed, as after a refined window) hold
                    # the arrived robots where they can: flown unheld, the refined open field's robots drifted
                    # (0.2 stops per robot, none held)
                    softs = [(False, True)]
                hopeful = k < optimistic + (len(tries) - len(attempts))
                # a leading attempt that fails leaves the rows as they were: the rows its rounds switched on made
                # the next attempts of clutter40@7's first window fail (piqp's iteration cap) and the window fly
                # the bold profile instead of the fast one x1.1
                rows = ((self.active.copy(), self.limit_rows.copy(), self._hard.copy(), list(self.plain_odds))
                        if name.startswith(LEADING) else None)
                variants, plain = softs + [(False, False)], None
                if (softs and hopeful and not self.cfg.time_refinement
                        and PLAIN_FAIL_WEIGHT * self.plain_odds[0] > self.plain_odds[1]):
                    # the plain variant first (PLAIN_FAIL_WEIGHT): where it has no solution, the variants are
                    # not tried
                    plain = self._solve(a, b, start, durations, rec, merged=merged, optimistic=hopeful)
                    if plain[0] is None:
                        variants = [(False, False)]
                for with_creep, hold in variants:
                    creep = c if with_creep else None
                    if plain is not None and creep is None and not hold:
                        sol, why = plain
                    else:
                        sol, why = self._solve(a, b, start, durations, rec, merged=merged, optimistic=hopeful,
                                               creep=creep, gradient=self.cfg.time_refinement, hold=hold)
                    if softs and hopeful and (with_creep, hold) in (softs[0], (False, False)):
                        soft = (with_creep, hold) != (False, False)
                        if sol is None and not soft:
                            self.plain_odds[0] += 1
                        elif sol is not None and soft:
                            self.plain_odds[1] += 1
                    release, cert = None, None
                    if sol is not None and softs and has_hold and not hold:
                        # the holds failed: hold the arrived robots that this solution keeps clear of the others
                        for release in self._releases(sol, a, b, start):
                            part = self._solve(a, b, start, durations, rec, merged=merged, optimistic=hopeful,
                                               gradient=self.cfg.time_refinement, hold=True, release=release)[0]
                            held_cert = None if part is None else self._certify(part, a)
                            if held_cert is not None and held_cert.ok:
                                sol, hold, cert = part, True, held_cert
                                break
                        else:
                            release = None
                    if sol is not None:
                        cert = cert or self._certify(sol, a)
                        if cert.ok:
                            chosen, rec.attempt, rec.piece_steps = sol, name, [int(g) for g in sizes]
                            rec.creep, rec.hold = creep is not None, hold
                            rec.released = [] if release is None else [int(i) for i in np.flatnonzero(release)]
                            break
                        why = "; ".join(cert.problems[:2])
                    what = name + (" with creep rows" if creep is not None else "") + (" with holds" if hold else "")
                    rec.failed.append(f"{label}{what}: {why}")
                    rec.note_unsolved(why)
                    log.info("window %d..%d, %s%s durations rejected: %s", a, b, label, what, why)
                if chosen is not None:
                    break
                if rows is not None:
                    self.active, self.limit_rows, self._hard, self.plain_odds = rows
                missed.append(np.asarray(durations, dtype=float))
            if chosen is not None:
                chosen = self._bisect(a, c, b, start, chosen, missed, rec, merged)
                break
        if chosen is None:
            merged, rec.piece_steps = None, [1] * flown
            durations = np.concatenate([base[:overlap], target])
            chosen = self._witness(a, b, durations, prev)
            cert = self._certify(chosen, a)
            if not cert.ok:
                raise UnsafeTrajectoryError(f"steps {a}..{b}: even the rest-to-rest witness is not certified "
                                            f"({'; '.join(cert.problems[:2])}); attempts: {'; '.join(rec.failed)}")
            rec.attempt = "witness"
        if self.cfg.time_refinement and rec.attempt != "witness":
            chosen = self._refine(chosen, a, start, rec, merged)
        else:
            self.unrefined = None  # nothing for the undo to take back (and not the window before's)
        rec.cost, rec.durations = chosen.cost, chosen.durations
        rec.solve_s = time.perf_counter() - tic
        return chosen, rec

    def _bisect(self, a: int, c: int, b: int, start: np.ndarray, chosen: _Solution, missed: list[np.ndarray],
                rec: WindowRecord, merged: np.ndarray | None) -> _Solution:
        """``chosen`` (certified), or, in a refined run, the window at durations between it and the last attempt
        before it that would have flown sooner (``missed``: the attempts without a certified solution), if
        certified there.

        The attempts are a ladder of whole profiles, each a few percent to a factor 1.5 slower than the one
        before; where the window fits between two rungs it flew the slower one. :data:`BISECTIONS` times, the
        geometric mean of the certified durations and the failed ones is solved (with the creep rows, holds and
        releases the chosen attempt needed) and kept if certified: each halves the gap in the logarithm.
        """
        flown = c - a
        ok = np.asarray(chosen.durations, dtype=float)
        faster = [d for d in missed if d[:flown].sum() < ok[:flown].sum() - SAME_LENGTH]
        if not BISECTIONS or not self.cfg.time_refinement or not faster:
            return chosen
        bad, release = faster[-1], None
        if rec.released:
            release = np.zeros(self.N, dtype=bool)
            release[rec.released] = True
        for _ in range(BISECTIONS):
            T = np.sqrt(ok * bad)
            sol = self._solve(a, b, start, T, rec, merged=merged, optimistic=True, creep=c if rec.creep else None,
                              gradient=True, hold=rec.hold, release=release)[0]
            if sol is not None and self._certify(sol, a).ok:
                ok, chosen = T, sol
                rec.bisected += 1
            else:
                bad = T
        return chosen

    def time_allocation(self, sol: _Solution, a: int, start: np.ndarray, rec: WindowRecord,
                        merged: np.ndarray | None = None) -> TimeAllocation:
        """The window's step durations as the variables of an NLP, from the QP's (``sol``).

        The objective is the window problem's optimum at given durations plus
        ``time_weight`` x flight time (per robot): f(T) = J*(T) + w N sum(T). Evaluating it
        solves the window QP (lazy rows and all); its gradient is exact, by the envelope
        theorem, from the QP's multipliers and the symbolic pieces' derivative in T
        (:meth:`~mrfswarm.continuous.formulation.WindowFormulation.duration_gradient`).
        Durations where the QP has no solution are not a number: Ipopt shortens its step
        there, and :func:`solvers.nlp.minimize` makes the other backends do the same
        (:mod:`solvers.nlp.evaluation`). Bounds: each step between a fifth of
        its nominal duration (at least 1 ms) and twice its witness or nominal one, and
        around ``sol``'s durations.

        Evaluations run a smaller iteration budget (the scaling's :data:`TRIAL_BUDGET`, the NLP backends'
        :data:`OPTIMISTIC_BUDGET`): a point the QP does not solve within it counts as one without a solution.

        Every evaluation starts from the lazy rows of the best point solved so far (those active when this is
        called, before any) and leaves ``self.active``/``self.limit_rows`` at the rows it needed; the caller puts back
        the rows of the point it keeps (:attr:`TimeAllocation.rows`, :attr:`TimeAllocation.base`).
        """
        M = len(sol.durations)
        b = a + M
        w = self.cfg.time_weight * self.N
        base = (self.active.copy(), self.limit_rows.copy())
        solved: dict[bytes, _Solution | None] = {}
        rows: dict[bytes, tuple[np.ndarray, np.ndarray]] = {}
        if sol.gradient is not None:  # the start point is the accepted QP itself: no second solve of it
            key = np.asarray(sol.durations, dtype=float).tobytes()
            solved[key], rows[key] = sol, (base[0].copy(), base[1].copy())

        # the scaling's trial points run the smaller budget; the NLP backends' the attempts' (TRIAL_BUDGET)
        scaling = self.cfg.refinement == "scaling"
        release = None
        if rec.released:
            release = np.zeros(self.N, dtype=bool)
            release[rec.released] = True

        def at(T: np.ndarray) -> _Solution | None:
            key = np.asarray(T, dtype=float).tobytes()
            if key not in solved:
                # every evaluation starts from the rows of the best point so far (the accepted QP's at first):
                # a far trial point (where every limit binds) does not burden the rest, and the rows a nearby
                # point needed are not found again, a round each (refined, in-process, the least of 3 runs, in two
                # rounds: forest 1.81 / 1.68 -> 1.75 / 1.59 s, rooms 1.49 / 1.40 -> 1.40 / 1.30; flights clutter40
                # 46.86 -> 46.62 s, aisles30 34.41 -> 34.30, rooms 24.91 -> 25.14, the rest the same)
                values = {k: s.cost + w * s.durations.sum() for k, s in solved.items() if s is not None}
                best = rows[min(values, key=values.__getitem__)] if values else base
                self.active, self.limit_rows = best[0].copy(), best[1].copy()
                solved[key] = self._solve(a, b, start, np.asarray(T, dtype=float), rec, gradient=True,
                                          merged=merged, optimistic=True, creep=rec.c if rec.creep else None,
                                          hold=rec.hold, release=release, trial=scaling)[0]
                rows[key] = (self.active, self.limit_rows)
            return solved[key]

        def fun(T: np.ndarray) -> float:
            s = at(T)
            return float("nan") if s is None else s.cost + w * float(np.sum(T))

        def grad(T: np.ndarray) -> np.ndarray:
            s = at(T)
            return np.full(M, np.nan) if s is None or s.gradient is None else s.gradient + w

        lower = np.minimum(np.maximum(0.2 * self.nominal[a:b], 1e-3), sol.durations)
        upper = np.maximum(2 * np.maximum(self.witness[a:b], self.nominal[a:b]), sol.durations)
        return TimeAllocation(NLPProblem(fun, grad, sol.durations, lower, upper), base, w, solved, rows)

    def _refine(self, sol: _Solution, a: int, start: np.ndarray, rec: WindowRecord,
                merged: np.ndarray | None = None) -> _Solution:
        """The window's step durations refined (:meth:`time_allocation`): by the multiplier scaling
        (:func:`~mrfswarm.continuous.duration_scaling.scale_durations`, ``cfg.refinement = "scaling"``) or by the
        NLP backend ``cfg.nlp`` (``"nlp"``).

        Every iterate is a solution of the window problem, so the result keeps the next
        window's feasibility argument; the best point the backend evaluated is kept if it
        certifies, lowers f and does not last longer than ``sol`` (the next best otherwise,
        and so on down to ``sol``). Without the last condition a point of lower snap but
        longer steps was kept: the corridor refined flew 22.4 s, now 20.4.
        """
        self.unrefined = None
        if self.cfg.refinement == "scaling" and sol.gradient is not None and not self._shortens_flown(sol, rec):
            log.info("window %d..%d: the scaling would lengthen every flown step: not refined", a,
                     a + len(sol.durations))
            return sol
        alloc = self.time_allocation(sol, a, start, rec, merged)
        if self.cfg.refinement == "scaling":
            scaled = scale_durations(alloc.problem, alloc.weight, self.cfg.derivative, total=sol.durations.sum())
            method, status = "scaling", scaled.status
        else:
            try:
                res = solvers.nlp.minimize(self._not_longer(alloc.problem, sol), self.cfg.nlp, self.nlp_options)
                method, status = res.backend, res.raw_status
            except SolverError as e:  # as a failed QP backend's windows fly their witness, the run goes on: the
                # points the backend had evaluated are window QPs' solutions, certified below like any other
                rec.refine_error = str(e).splitlines()[0] if str(e) else type(e).__name__
                method, status = self.cfg.nlp, f"failed: {rec.refine_error}"
        before = sol.cost + alloc.weight * sol.durations.sum()
        found = {k: s for k, s in alloc.solved.items() if s is not None}
        tried = sorted((s.cost + alloc.weight * s.durations.sum(), k) for k, s in found.items())
        for value, key in tried:  # the best point the backend saw first
            if value >= before:
                break
            best = found[key]
            if np.abs(best.durations - sol.durations).max() <= SAME_LENGTH:
                # the QP solved again at its own durations (lower by its tolerance), or at them but for rounding (the
                # scaling's cap at their sum moved the refined arena's third window's steps by 6e-17 s): not a
                # refinement
                continue
            if best.durations.sum() <= sol.durations.sum() + SAME_LENGTH and self._certify(best, a).ok:
                rec.refined = True
                self.unrefined = (sol, (alloc.base[0], alloc.base[1], self._hard.copy()))
                self.active, self.limit_rows = alloc.rows[key]
                return best
        self.active, self.limit_rows = alloc.base
        log.info("window %d..%d: time refinement (%s) kept the QP's durations (%s)", a, a + len(sol.durations),
                 method, status)
        return sol

    def _not_longer(self, problem: NLPProblem, sol: _Solution, backend: str | None = None) -> NLPProblem:
        """``problem`` with the row sum(T) <= ``sol``'s sum where the NLP backend (``backend``, by default
        ``cfg.nlp``) takes linear rows: the scaling's cap (``scale_durations``, ``total``), and what :meth:`_refine`
        keeps.

        The windows' optimum of snap + weight x time often lies at longer steps than the QP's (the profiles are
        fast): without the row the NLP spent its iterations there, on points the refinement then rejects.
        With it (refined by Ipopt, in-process, one run each, 2026-11-29): the forest 22.10 -> 21.20 s (4 -> 8 of
        9 windows refined), rooms 24.44 -> 23.72, the trap 24.93 -> 24.68, the arena 5.71 -> 5.53, the corridor
        19.47 -> 19.30, the doorway 10.455 -> 10.468; SLSQP, sqpmethod and trust-constr 1.3-3.5 % sooner on the
        forest and rooms. A backend without linear rows (L-BFGS-B) gets the bounds alone.
        """
        if not solvers.nlp.BACKENDS.get(backend or self.cfg.nlp).capabilities.linear_constraints:
            return problem
        return dataclasses.replace(problem, A=np.ones((1, len(sol.durations))), lb=-np.inf,
                                   ub=float(sol.durations.sum()))

    def _shortens_flown(self, sol: _Solution, rec: WindowRecord) -> bool:
        """Whether the multiplier scaling's first step from ``sol`` (its gradient, free: the attempt solved it)
        shortens any step the window flies (a..c), capped at ``sol``'s sum as the refinement is.

        Where it would lengthen every flown step (their multipliers press: a limit binds, as on the forest's
        first windows at the fast profile), the refinement could only move time within the tail, which the
        next window plans again: it spent its QP solves there for a flight no sooner. Skipping those windows
        (flight_quality.py --variants refined --baseline 7941fb2, one run): the open field's refined planning
        20.4 -> 13.7 s (33.51 -> 33.71 s flight), forest 24.51 -> 24.08 s, arena 6.26 -> 6.15, corridor
        19.49 -> 19.61, rooms 24.85 -> 24.80, doorway, trap, clutter40 and aisles30 the same flights.
        """
        T = np.asarray(sol.durations, dtype=float)
        assert sol.gradient is not None
        w = self.cfg.time_weight * self.N
        trial = T * step_factors(sol.gradient, w, self.cfg.derivative)
        if trial.sum() > T.sum():
            trial *= T.sum() / trial.sum()
        flown = rec.c - rec.a
        return bool(np.any(trial[:flown] < T[:flown]))

    # ------------------------------------------------------------------ run
    @property
    def retimes(self) -> bool:
        """Whether the flight is re-timed as a whole once its windows are planned (:meth:`_retime`): at most
        :data:`RETIME_HORIZONS` horizons of steps in more than one window, on the default time grid (not with a
        cruise ``speed``, whose durations are the user's pace) and without rest-to-rest seams."""
        cfg = self.cfg
        return (cfg.speed is None and cfg.seam != "rest" and 1 < len(self.windows())
                and self.T <= RETIME_HORIZONS * self.horizon)

    def run(self, on_window: Callable[[WindowRecord], None] | None = None) -> ContinuousPlan:
        """Plan every window; returns the assembled, certified trajectories."""
        if not (self.workers > 1 and self.N >= PARALLEL_ROBOTS):
            return self._run(on_window)
        try:
            with process_pool(self.workers) as self._pool:  # Ctrl-C stops the chunks still being solved
                return self._run(on_window)
        finally:
            self._pool = None

    def _run(self, on_window: Callable[[WindowRecord], None] | None) -> ContinuousPlan:
        cfg, N, T = self.cfg, self.N, self.T
        q, pm = cfg.derivative, piece_maps(cfg.degree, cfg.derivative)
        tic = time.perf_counter()
        if T == 0:  # nobody moved: hover in place for a moment
            hover = [PiecewisePolynomial(np.array([1.0]), np.concatenate(
                [self.X[0, i][None, None, :], np.zeros((1, cfg.degree, self.dim))], axis=1)) for i in range(N)]
            return self._finish(hover, np.array([0.0, 1.0]), [], tic, np.array([0, 1]))
        Y = np.zeros((T + 1, N, q, self.dim))
        Y[0, :, 0] = self.X[0]
        B = np.zeros((T, N, pm.nz - 2 * q, self.dim))
        durations = np.zeros(T)
        records, prev, used = [], None, 0
        windows = self.windows()
        # the last window brakes to rest at the goal: one piece over several of its steps is all but fixed by
        # its two ends (swarm100: infeasible at every duration, 32 pieces), so its steps are kept out of the
        # share and it gets what is left
        last = windows[-1][0]
        reserve = T - last
        # a window flies at least one piece: with more windows than pieces the flight cannot fit however its
        # windows merge, and merging would only cost time (a 1000-robot crossing of 232 steps ran for over 20
        # minutes trying) and speed: fly one piece per step and report it
        merge = bool(cfg.max_pieces) and len(windows) <= cfg.max_pieces
        if cfg.max_pieces and not merge:
            # the fewest steps a window must fly for max_pieces windows to cover the flight
            need = math.ceil(math.ceil(T / cfg.max_pieces) / cfg.execution)
            log.warning("%d windows of %d steps cannot fit smoothing.max_pieces = %d pieces (a window flies one "
                        "piece at least): one piece per step, %d per robot. Fitting needs fewer windows, "
                        "smoothing.horizon >= %d at execution %g (not always enough: a window whose merged pieces "
                        "have no solution keeps more; and slow to plan with many robots), or a shorter flight; "
                        "smoothing.max_pieces = 0 leaves the limit off", len(windows), T, cfg.max_pieces, T, need,
                        cfg.execution)

        def commit(a: int, c: int, b: int, sol: _Solution) -> tuple | None:
            Y[a:c + 1] = sol.Y[:, :c - a + 1].transpose(1, 0, 2, 3)
            B[a:c] = sol.B[:, :c - a].transpose(1, 0, 2, 3)
            durations[a:c] = sol.durations[:c - a]
            return (a, b, sol) if c < b else None

        before = None  # the last window, when refined: (a, c, b, its solution, the one unrefined, its rows)
        first = PROFILES[0][0] if self.profiles else "nominal"  # a window's first attempt
        for a, c, b in windows:
            if not merge:
                pieces = None
            elif a == last:
                pieces = window_pieces(c - a, T - a, cfg.max_pieces - used)
            else:
                pieces = window_pieces(c - a, last - a, cfg.max_pieces - used - reserve)
            sol, rec = self._plan_window(a, c, b, Y[a], prev, pieces)
            if before is not None and rec.attempt != first:
                sol, rec = self._undo_refinement(before, (a, c, b), sol, rec, Y, commit, pieces, records[-1])
            used += rec.pieces
            prev = commit(a, c, b, sol)
            before = None if self.unrefined is None else (a, c, b, sol, *self.unrefined)
            records.append(rec)
            if on_window is not None:
                on_window(rec)
        sizes = [g for rec in records for g in rec.piece_steps]
        retimed = None
        if self.retimes:
            retimed = self._retime(Y, B, durations, records, np.array(sizes))
        trajectories = [hermite_trajectory(Y[:, i], B[:, i], durations, cfg.degree, q) for i in range(N)]
        knots = np.concatenate([[0.0], np.cumsum(durations)])
        plan = self._finish(merge_trajectories(trajectories, np.array(sizes), q), knots, records, tic,
                            np.concatenate([[0], np.cumsum(sizes)]))
        plan.retimed, plan.horizon = retimed, self.horizon
        return plan

    def _retime(self, Y: np.ndarray, B: np.ndarray, durations: np.ndarray, records: list[WindowRecord],
                sizes: np.ndarray) -> float | None:
        """The whole flight planned as one window at its flown durations times each of :data:`RETIME_FACTORS` in
        turn, until one has no certified solution; the last certified one replaces ``Y``, ``B`` and ``durations``
        (in place). Returns its factor, or None where even the first has none.

        The windows' solutions, put together, are a solution of the whole flight's problem at the flown durations:
        the regions and corridors are the same, every seam is continuous, and the flight ends at rest. Each
        window, though, planned its tail to rest for the next one's sake, and flew its steps so that it could; the
        whole flight's QP has no such tails, and the same durations a few per cent shorter still have solutions.
        The creep rows stay on where a window had them (no robot stops where it drifted through a wait), and the
        arrived robots stay held where a window held them (every one held at every step it is held in: where a
        window released some, the whole flight may have no solution, and is not re-timed).
        The solution kept is certified for all t like every window's.
        """
        T = self.T
        start = Y[0]
        merged = merged_knots(sizes, T) if (sizes > 1).any() else None
        creep = T if any(rec.creep for rec in records) else None
        hold = any(rec.hold for rec in records)
        rec = WindowRecord(a=0, c=T, b=T)
        best, kept = None, None
        for factor in RETIME_FACTORS:
            sol = self._solve(0, T, start, durations * factor, rec, merged=merged, creep=creep, hold=hold)[0]
            if sol is None or not self._certify(sol, 0).ok:
                break
            best, kept = sol, factor
        log.info("the whole flight re-timed: %s (%d QP rounds)", "not shorter" if kept is None else
                 f"x{kept:g}, {durations.sum() * kept:.3f} s", rec.rounds)
        if best is None:
            return None
        Y[:] = best.Y.transpose(1, 0, 2, 3)
        B[:] = best.B.transpose(1, 0, 2, 3)
        durations[:] = best.durations
        return kept

    def _undo_refinement(self, before: tuple, window: tuple[int, int, int], sol: _Solution, rec: WindowRecord,
                         Y: np.ndarray, commit: Callable[[int, int, int, _Solution], tuple | None], pieces: int | None,
                         refined_rec: WindowRecord) -> tuple[_Solution, WindowRecord]:
        """The window after a refined one did not fly its first attempt: plan it again from the refined
        window's solution before the refinement, and keep whichever pair flies its flown steps sooner.

        The refinement shortens one window alone: it can leave the swarm faster than the next window's
        profiles can take over from (forest of the flight-quality bench: 2 of 9 windows flew the previous
        window's braking tail after a refined one, and the refined flight took 26.3 s against 26.1 unrefined;
        window3d's last window fell from the fast profile to the bold one, 12.4 s against 12.0). Called only
        then, and planned again only when the unrefined window and the next one's fastest attempt would fly
        sooner than the refined pair (aisles30 refined: 13.8 -> 12.0 s of planning, the same flight), so it
        costs one window's planning where it may pay.
        """
        ka, kc, kb, ksol, unrefined, rows = before
        a, c, b = window
        refined_s = float(ksol.durations[:kc - ka].sum() + sol.durations[:c - a].sum())
        fastest = self._profile_attempts(a, c, b)[0][1]
        if unrefined.durations[:kc - ka].sum() + fastest[:c - a].sum() >= refined_s:
            return sol, rec  # even its fastest attempt would not make up for the refinement
        after = (self.active.copy(), self.limit_rows.copy(), self._hard.copy(), self.unrefined)
        self.active, self.limit_rows, self._hard = (x.copy() for x in rows)
        prev = commit(ka, kc, kb, unrefined)
        again, again_rec = self._plan_window(a, c, b, Y[a], prev, pieces)
        unrefined_s = float(unrefined.durations[:kc - ka].sum() + again.durations[:c - a].sum())
        if unrefined_s < refined_s:
            log.info("window %d..%d: refinement undone (the next window fell back to %s: %.2f s against %.2f)",
                     ka, kb, rec.attempt, refined_s, unrefined_s)
            refined_rec.refined, refined_rec.cost, refined_rec.durations = False, unrefined.cost, unrefined.durations
            again_rec.failed[:0] = [f"after window {ka}..{kb} refined: fell back to {rec.attempt}"]
            return again, again_rec
        self.active, self.limit_rows, self._hard, self.unrefined = after
        commit(ka, kc, kb, ksol)
        return sol, rec

    def _finish(self, trajectories: list[PiecewisePolynomial], knots: np.ndarray, records: list[WindowRecord],
                tic: float, piece_steps: np.ndarray) -> ContinuousPlan:
        smoothing_s = time.perf_counter() - tic - self._check_s
        t0 = time.perf_counter()
        regions = self.regions if self.T else _hover_regions(self.X[0], self.radius)
        cert = certify(trajectories, knots, regions, self.distance, self.limits, self.scale)
        if not cert.ok:  # each window was certified; the whole must be too (a bug otherwise, never a silent output)
            raise UnsafeTrajectoryError(f"assembled trajectories not certified: {cert.problems[0]}")
        steps = step_pieces(trajectories, knots)  # the same curves, one piece per step: what the checks expect
        assert not isinstance(steps, str), steps  # certify split them just now
        v, acc, jerk = (max_derivative_norm_all(steps, k) for k in (1, 2, 3))
        min_sep = exact_min_separation(steps, 2 * self.grid.resolution, scale=self.scale)
        clearance = sampled_clearance(steps, self.grid)
        sampled = None
        if self.cfg.check_rate_hz > 0:
            times = uniform_times(0.0, float(knots[-1]), self.cfg.check_rate_hz)
            pts = np.stack([tr.evaluate(times) for tr in trajectories], axis=1)
            sampled = check_positions(times, pts, self.grid, self.scale)
        check_s = time.perf_counter() - t0 + self._check_s
        pieces = [tr.pieces for tr in trajectories]
        max_pieces = self.cfg.max_pieces
        if max_pieces and max(pieces) > max_pieces:
            log.warning("%d robots fly more than smoothing.max_pieces = %d pieces (up to %d, %d steps): the flight "
                        "does not fit", sum(p > max_pieces for p in pieces), max_pieces, max(pieces), self.T)
        return ContinuousPlan(trajectories, knots, regions, self.seps, records, cert, v, acc, jerk, min_sep, clearance,
                              sampled, {"regions": self.regions_s, "smoothing": smoothing_s, "checking": check_s},
                              np.asarray(piece_steps), max_pieces, pieces, self.downwash)


def solve_window(spec: WindowSpec, durations: np.ndarray, backend: str, options: QPOptions,
                 gradient: bool = False) -> tuple | str:
    """Solve one chunk's QP: its robots' knot derivatives, bubbles, snap integrals and (if asked, and
    the backend gives multipliers) each robot's share of the gradient in the durations; or why it failed (a
    :class:`Rejection`, with the backend's status where it ended without a solution).

    A plain function of picklable data, so chunks can be solved in worker processes (or,
    later, on a cluster). The process's :data:`~mrfswarm.continuous.window_cache.WINDOWS`
    keeps the problems of the last specs: solved again at other durations, they reuse
    their formulation and setup.
    """
    try:
        form, sol = WINDOWS.solve(spec, durations, backend, options)
    except SolverError as e:
        return Rejection(str(e), e.status if isinstance(e, SolveFailedError) else None)
    x = form.exact_ends(sol.x)
    Y, B = form.unpack(x)
    if spec.merged is not None:  # the merge rows are met to the solver's tolerance: make them exact
        Y, B = project_blocks(Y, B, durations, spec.merged, spec.degree, spec.derivative)
    grad = None
    if gradient and sol.y is not None:
        grad = form.duration_gradient(sol.x, sol.y, durations)
    return Y, B, form.robot_objectives(x, durations), grad


def _braking(factor: float) -> str:
    """The name of the last window's attempt that brakes ``factor`` times longer (:data:`FINAL_BRAKING`)."""
    return f"fast, braking x{factor:g}"


def _slower(factor: float) -> str:
    """The name of the attempt at the fast durations ``factor`` times longer (:data:`FAST_SLOWER`)."""
    return f"fast x{factor:g}"


def _piece_options(pieces: int, steps: int) -> list[int]:
    """Pieces to try for ``steps`` steps, from ``pieces`` up: doubling, then one per step."""
    out = [max(1, min(pieces, steps))]
    while out[-1] < steps:
        out.append(min(2 * out[-1], steps))
    return out


def chunk_size(n: int) -> int:
    """Robots per chunk when ``n`` robots are solved: about ``CHUNK_ROBOTS``, the chunks alike in size
    (30 robots make three chunks of 10, not 12, 12 and 6, so the workers finish together; the chunks'
    packing, :func:`pack_groups`, may still leave the last one smaller)."""
    return max(1, math.ceil(n / max(1, math.ceil(n / CHUNK_ROBOTS))))


def pack_groups(groups: list[np.ndarray], size: int) -> list[np.ndarray]:
    """Independent groups of robots packed, in order, into chunks of at most ``size`` robots.

    A group larger than ``size`` is a chunk of its own. The packing depends on the groups
    only (not on how many workers solve them), so a plan is the same with any number of
    workers.
    """
    chunks: list[np.ndarray] = []
    current: list[np.ndarray] = []
    count = 0
    for g in sorted(groups, key=lambda g: int(g[0])):
        if count and count + len(g) > size:
            chunks.append(np.concatenate(current))
            current, count = [], 0
        current.append(g)
        count += len(g)
    if current:
        chunks.append(np.concatenate(current))
    return [np.sort(c) for c in chunks]


def _hover_regions(X: np.ndarray, radius: float) -> Regions:
    """A point region per robot (the hover of a plan without steps)."""
    N, d = X.shape
    return Regions(np.broadcast_to(np.eye(d), (1, N, d, d)).copy(), X[None].copy(), X[None].copy(),
                   np.zeros((1, N), dtype=bool), radius)


def exact_min_separation(trajectories: list[PiecewisePolynomial], reach: float, block: int = 8,
                         scale: np.ndarray | None = None) -> float:
    """The exact smallest distance between two robots over trajectories on one time grid.

    With ``scale`` (d,), the distance is :math:`\\|(p_i - p_k) \\odot s\\|` (the
    downwash-scaled metric, :func:`mrfswarm.geometry.downwash_scale`): the trajectories
    scaled axis by axis are polynomials too, so the same exact search runs on them.

    Pairs whose control-point boxes in a step stay ``reach`` apart are skipped (``reach``
    grows until the minimum is below it); for the others the minimum of :math:`|p_i(t) - p_k(t)|`
    over each piece is found at the piece's ends or at a real root of the derivative of
    its square. Two passes over the steps, at least ``block`` steps at a time (and enough for
    :data:`~mrfswarm.trajectory.piece_stack.PIECE_CHUNK` pieces: memory stays that of a few
    steps at a thousand robots):

    1. an upper bound: the smallest distance of two robots at 9 times of a step, over the
       pairs whose boxes come nearer than ``reach`` and than the bound so far (no other
       pair can lower it), keeping those pairs;
    2. the exact minimum over the kept pairs whose boxes, then whose relative control
       points' hull (a lower bound per pair and step), come within the final bound.

    On a 1000-robot crossing of 300 steps, pass 1 meets 11 thousand (pair, step) and
    pass 2 bounds 8 thousand by their hull, where the million within ``reach`` all were
    before.
    """
    from mrfswarm.continuous.certificate import hull_distance_from_origin
    from mrfswarm.continuous.regions import near_pairs
    from mrfswarm.trajectory.bernstein import control_point_matrix
    from mrfswarm.trajectory.piece_stack import PIECE_CHUNK, map_coefficients, squared_norms, stacked_tau_coefficients
    from mrfswarm.trajectory.retiming import piece_extrema

    N = len(trajectories)
    if N < 2:
        return float("inf")
    M = trajectories[0].pieces
    C = stacked_tau_coefficients(trajectories)  # (K, N M, d), robot after robot
    K, d = len(C), C.shape[-1]
    C = C.reshape(K, N, M, d)
    if scale is not None and not np.all(scale == 1.0):
        C = C * np.asarray(scale, dtype=float)
    P = map_coefficients(control_point_matrix(K - 1), C)  # (K, N, M, d) position control points
    lo, hi = P.min(axis=0), P.max(axis=0)  # (N, M, d)
    span = float((hi.max(axis=(0, 1)) - lo.min(axis=(0, 1))).max()) + reach
    tau = np.linspace(0.0, 1.0, 9)
    V = tau[:, None] ** np.arange(K)[None, :]  # (9, K)
    tol = 1e-9  # rounding: a bound attained at a piece's end
    steps = max(block, -(-PIECE_CHUNK // N))

    def box_gap(i: np.ndarray, k: np.ndarray, j: np.ndarray | int) -> np.ndarray:
        return np.linalg.norm(np.maximum(0.0, np.maximum(lo[i, j] - hi[k, j], lo[k, j] - hi[i, j])), axis=-1)

    while True:  # pairs left out are >= reach apart, so the minimum is exact once it is <= reach
        best, found = np.inf, []
        for j0 in range(0, M, steps):
            j1 = min(j0 + steps, M)
            X = map_coefficients(V, C[:, :, j0:j1])  # (9, N, b, d) positions at the 9 times
            for j in range(j0, j1):
                pairs = near_pairs(lo[:, j], hi[:, j], min(reach, best))
                i, k = pairs[:, 0], pairs[:, 1]
                near = box_gap(i, k, j) < best
                i, k = i[near], k[near]
                if len(i):
                    best = min(best, float(np.sqrt(squared_norms(X[:, i, j - j0] - X[:, k, j - j0]).min())))
                    found.append(np.stack([i, k, np.full(len(i), j)]))
        if best <= reach or reach > span:
            break
        reach *= 4
    if not found:
        return best
    i, k, j = np.concatenate(found, axis=1)
    i, k, j = (v[box_gap(i, k, j) <= best + tol * (1.0 + best)] for v in (i, k, j))
    lower = hull_distance_from_origin((P[:, i, j] - P[:, k, j]).transpose(1, 0, 2))  # a lower bound per pair
    keep = lower <= best + tol * (1.0 + best)
    if keep.any():
        i, k, j = i[keep], k[keep], j[keep]
        vals, _ = piece_extrema(np.ascontiguousarray((C[:, i, j] - C[:, k, j]).transpose(1, 0, 2)), minimum=True)
        best = min(best, float(vals.min()))
    return best


def sampled_clearance(trajectories: list[PiecewisePolynomial], grid: OccupancyGrid, per_piece: int = 16) -> float | None:
    """Smallest distance from a robot's centre to an occupied cell or the map's edge, at ``per_piece`` samples per
    piece."""
    from mrfswarm.continuous.sampled_check import voxel_clearance

    knots = trajectories[0].knots
    tau = np.linspace(0.0, 1.0, per_piece)
    times = (knots[:-1, None] + tau[None, :] * np.diff(knots)[:, None]).ravel()
    pts = np.stack([tr.evaluate(times) for tr in trajectories], axis=1).reshape(-1, grid.ndim)
    clr = voxel_clearance(grid.occupied, (pts - np.asarray(grid.origin)) / grid.resolution)
    return None if clr is None else clr * grid.resolution
