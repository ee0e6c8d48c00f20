"""The continuous stage: receding-horizon min-snap smoothing with certified separation.

Time grid. Every robot uses the same knot times: discrete step j is reached at t_j.
Step j lasts dt_j = max(longest move of the step, one cell) / speed, times a factor
alpha >= 1 set when the step is first planned (to meet the velocity and acceleration
limits, or to repair a window); once planned, a step's duration is kept.

Reference. The discrete paths are pruned once, in blocks between consecutive execution
points (every E = round(execution * horizon) steps), so at every block boundary each
robot is exactly on its discrete cell. Robot i's reference is its pruned path (chords
between kept waypoints, positions at the integer steps on the chords), each step
traversed with the min-snap time law s(tau) = 35 tau^4 - 84 tau^5 + 70 tau^6 - 20 tau^7
from t_j to t_{j+1}. All robots share that time law, so two robots' relative motion
within a step is a straight segment in s: the discrete stage's guarantee (>= 1 cell
apart during every step, half a cell from every obstacle) holds for the references
whenever it holds for the chord positions at the integer steps, which is checked
exactly per block (:func:`mrfswarm.motion.step_min_separation`); a robot whose chords
would come too close to another's is un-pruned in that block (its reference is then its
discrete motion, which is safe). The law is at rest (up to jerk) at every step, so the
reference is itself a feasible trajectory (one degree-7 piece per step) whatever
corners it turns.

Trajectory. One polynomial piece per step; the knot of step j is at the reference's
position, exactly for kept waypoints and within the corridor box for pruned ones
(pruning frees waypoints, as in the paper, without giving up the time-indexed
guarantee). The trajectory stays in a box of half-width r (``smoothing.corridor``
cells) around its reference at sample times, so it is at most sqrt(2) r from it and two
robots are at least 1 - 2 sqrt(2) r cells apart at the samples (>= ``safety_distance``
by the config's validation). Every window is then checked by sampling (200 Hz) over
its whole span, with a margin of v_max / 200 Hz on the separation (and half that from
obstacles) so that what holds at the samples holds at all times in between; a window
that fails is repaired (denser corridor samples, tighter corridor, slower timing) or
the run fails with :class:`UnsafeTrajectoryError`.

Seams. ``rest`` (the paper): each executed part of a horizon starts and ends at rest;
since rest at the execution point decouples it from the rest of the horizon, the window
solved is the executed steps [a, a + E]. ``continuous``: the window [a, a + H] starts
with the position, velocity, acceleration and jerk of the previous window's trajectory
at a and ends at rest; its first E steps are executed, so the whole trajectory is
continuous up to jerk. The previous trajectory over the overlap, followed by the
reference, is a feasible point of the new window (same reference, same step durations),
so the QP always has a solution; if the new window still cannot be certified, the
previous window's checked remainder is flown instead and the next window starts from
rest at its end.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from mrfswarm.config import SmoothingConfig
from mrfswarm.continuous_check import SampledCheck, check_positions, sample_times
from mrfswarm.errors import UnsafeTrajectoryError
from mrfswarm.maps import OccupancyGrid
from mrfswarm.motion import MIN_SEPARATION, step_min_separation
from mrfswarm.pruning import prune_robot
from mrfswarm.trajectory import (
    Corridor,
    MinSnapBatchSolver,
    MinSnapProblem,
    PiecewisePolynomial,
    PolylineReference,
    concatenate,
    max_derivative_norms,
)
from mrfswarm.trajectory.corridor import evaluate_reference
from mrfswarm.trajectory.corridor import sample_times as corridor_sample_times
from solvers.errors import InfeasibleError, SolverError
from solvers.qp import Options as QPOptions

log = logging.getLogger(__name__)

#: The reference's time law within each step (rest up to jerk at both ends of a step).
TIME_LAW = "smooth"
#: Sampling rate of the safety check (the design asks for at least 100 Hz).
CHECK_RATE_HZ = 200.0
#: Repairs tried on a window before falling back or failing.
MAX_REPAIRS = 6
#: Time-scaling rounds tried to meet the velocity and acceleration limits.
MAX_LIMIT_ROUNDS = 12
#: A window slower than this factor means the limits cannot be met.
MAX_ALPHA = 1e3


@dataclass
class WindowRecord:
    """What happened in one planning window (steps a..b planned, a..c executed)."""

    a: int
    c: int
    b: int
    alpha: float = 1.0
    repairs: list[str] = field(default_factory=list)
    samples_per_step: int = 0
    corridor: float = 0.0
    solve_s: float = 0.0
    fallback: bool = False
    check: SampledCheck | None = None


@dataclass
class ContinuousPlan:
    """The smooth trajectories of every robot and what the continuous stage measured.

    Attributes
    ----------
    trajectories
        One 2-D :class:`PiecewisePolynomial` per robot, all starting at time 0 and
        lasting ``makespan_s``.
    knot_times
        (T + 1,) time at which each discrete step is reached (the common time grid).
    reference
        (T + 1, N, 2) the reference positions (metres) at the knots: the pruned chords.
    kept
        Per robot, the kept (exact) waypoints' step indices.
    windows
        One record per planning window.
    check
        The sampled check of the whole flight.
    v_max, a_max, j_max
        Achieved maximum speed, acceleration and jerk over all robots.
    unpruned
        (robot, block) pairs whose pruned chords were unsafe and were un-pruned.
    """

    trajectories: list[PiecewisePolynomial]
    knot_times: np.ndarray
    reference: np.ndarray
    kept: list[np.ndarray]
    windows: list[WindowRecord]
    check: SampledCheck
    v_max: float
    a_max: float
    j_max: float
    unpruned: int = 0
    timings: dict[str, float] = field(default_factory=dict)

    @property
    def makespan_s(self) -> float:
        return float(self.knot_times[-1])

    def positions(self, times: np.ndarray) -> np.ndarray:
        """(S, N, 2) every robot's position at ``times``."""
        return np.stack([tr.evaluate(times) for tr in self.trajectories], axis=1)


def step_durations(paths: np.ndarray, resolution: float, speed: float) -> np.ndarray:
    """Nominal dt_j: the step's longest move (at least one cell), in metres, over ``speed``."""
    moves = np.hypot(*np.diff(paths.astype(float), axis=0).transpose(2, 0, 1))  # (T, N)
    longest = moves.max(axis=1, initial=0.0) if moves.size else np.zeros(0)
    return np.maximum(longest, 1.0) * resolution / speed


def chord_positions(path: np.ndarray, kept: np.ndarray) -> np.ndarray:
    """(T + 1, 2) positions at every step on the chords between ``kept`` steps of ``path``."""
    steps = np.arange(len(path))
    return np.stack([np.interp(steps, kept, path[kept, d].astype(float)) for d in range(2)], axis=1)


def execution_blocks(T: int, E: int) -> list[tuple[int, int]]:
    """[(0, E), (E, 2E), ..., (., T)]: the stretches between execution points."""
    return [(a, min(a + E, T)) for a in range(0, T, E)]


def safe_pruning(paths: np.ndarray, free: np.ndarray, E: int) -> tuple[list[np.ndarray], int]:
    """Kept waypoints per robot: pruned per execution block, un-pruned where unsafe.

    Returns
    -------
    kept
        Per robot, sorted step indices (block boundaries always included).
    unpruned
        How many (robot, block) prunings were undone because the chords came closer
        than one cell to another robot's.
    """
    T, N = len(paths) - 1, paths.shape[1]
    blocks = execution_blocks(T, E)
    kept_sets: list[set[int]] = [set() for _ in range(N)]
    unpruned = 0
    for a, b in blocks:
        block = [np.array(prune_robot(paths, free, i, a, b)) for i in range(N)]
        full = np.arange(a, b + 1)
        discrete = paths[a:b + 1].astype(float)
        while True:
            R = np.stack([np.stack([np.interp(full, k, paths[k, i, d].astype(float)) for d in range(2)], axis=1)
                          for i, k in enumerate(block)], axis=1)  # (b - a + 1, N, 2)
            bad: set[int] = set()
            for j in range(b - a):
                d, pair = step_min_separation(R[j], R[j + 1])
                if d < MIN_SEPARATION - 1e-9 and pair is not None:
                    # un-prune the robots whose chords differ from their discrete motion
                    bad.update(p for p in pair if not np.allclose(R[:, p], discrete[:, p]))
            if not bad:
                break
            for i in bad:
                block[i] = full
                unpruned += 1
        for i in range(N):
            kept_sets[i].update(block[i].tolist())
    kept = [np.array(sorted(k | {0, T})) for k in kept_sets]
    return kept, unpruned


@dataclass
class _Attempt:
    """What repairs change within a window."""

    alpha: float
    samples_per_step: int
    corridor: float


class RecedingHorizon:
    """Smooths discrete paths window by window on one common time grid.

    Parameters
    ----------
    paths
        (T + 1, N, 2) discrete paths in cells.
    grid
        The occupancy grid (for world coordinates and checks).
    cfg
        The smoothing settings.
    backend
        QP backend name for every solve (default ``cfg.backend``).
    corridor_samples
        Corridor samples per discrete step (before repairs).
    """

    def __init__(self, paths: np.ndarray, grid: OccupancyGrid, cfg: SmoothingConfig, backend: str | None = None,
                 corridor_samples: int = 6, qp_options: QPOptions | None = None) -> None:
        self.paths = np.asarray(paths, dtype=np.intp)
        self.grid = grid
        self.cfg = cfg
        self.backend = backend or cfg.backend
        self.corridor_samples = corridor_samples
        self.res = grid.resolution
        self.T, self.N = len(self.paths) - 1, self.paths.shape[1]
        self.E = max(1, int(round(cfg.execution * cfg.horizon)))
        self.dt = step_durations(self.paths, self.res, cfg.speed)
        self.qp_options = qp_options or QPOptions(eps_abs=1e-7, eps_rel=1e-7, max_iter=50000)
        self._check_s = 0.0
        self._batch = MinSnapBatchSolver(self.backend, self.qp_options)  # fails now on an unknown backend
        t0 = time.perf_counter()
        self.kept, self.unpruned = safe_pruning(self.paths, grid.free, self.E)
        self.reference = grid.cell_to_world(np.stack([chord_positions(self.paths[:, i], self.kept[i])
                                                      for i in range(self.N)], axis=1))  # (T + 1, N, 2)
        self.exact = np.zeros((self.T + 1, self.N), dtype=bool)
        for i, k in enumerate(self.kept):
            self.exact[k, i] = True
        self.pruning_s = time.perf_counter() - t0

    # ------------------------------------------------------------------ windows
    def windows(self) -> list[tuple[int, int, int]]:
        """(a, c, b): planned steps a..b, executed a..c (without fallbacks)."""
        out, a = [], 0
        while a < self.T:
            c = min(a + self.E, self.T)
            b = c if self.cfg.seam == "rest" else min(a + self.cfg.horizon, self.T)
            out.append((a, c, b))
            a = c
        return out

    # ------------------------------------------------------------------ solving
    def _corridor(self, i: int, a: int, b: int, t: np.ndarray, K: int, half: np.ndarray) -> Corridor:
        """Boxes of half-width ``half[j]`` (metres, per step) around robot i's reference."""
        ref = PolylineReference(self.reference[a:b + 1, i], t[a:b + 1], law=TIME_LAW)
        times = corridor_sample_times(np.diff(t[a:b + 1]), K, float(t[a]))
        centre = evaluate_reference(ref, times, 2)
        h = half[:, None, None]
        return Corridor(centre - h, centre + h)

    def _problem(self, i: int, a: int, b: int, t: np.ndarray, K: int, half: np.ndarray, start) -> MinSnapProblem:
        """Robot i's smoothing problem over steps a..b (local time 0 at t[a]), one piece per step."""
        waypoints = self.reference[a:b + 1, i].copy()
        # a pruned knot may move within the narrower of its two pieces' boxes; windows
        # start and end exactly on a waypoint
        knot_half = np.minimum(np.r_[half[0], half], np.r_[half, half[-1]])
        tol = np.where(self.exact[a:b + 1, i], 0.0, knot_half)
        tol[0] = tol[-1] = 0.0
        if isinstance(start, tuple):  # continuous seam: the previous trajectory's state
            waypoints[0], start = start
        return MinSnapProblem(waypoints, np.diff(t[a:b + 1]), degree=self.cfg.degree,
                              derivative=self.cfg.derivative, start=start, end="rest",
                              corridor=self._corridor(i, a, b, t, K, half), waypoint_tolerance=tol)

    def _check(self, trajs: list[PiecewisePolynomial], t0: float, t1: float) -> SampledCheck:
        tic = time.perf_counter()
        times = sample_times(0.0, t1 - t0, CHECK_RATE_HZ)
        pts = np.stack([tr.evaluate(times) for tr in trajs], axis=1)
        out = check_positions(times + t0, pts, self.grid)
        self._check_s += time.perf_counter() - tic
        return out

    def _unsafe(self, chk: SampledCheck) -> str:
        # Between two samples h = 1/rate apart, robots moving at most v_max close in on each
        # other by at most v_max h (and on a wall by v_max h / 2), so these margins make the
        # sampled check hold for all times of trajectories that meet the speed limit.
        margin = self.cfg.v_max / CHECK_RATE_HZ
        limit = self.cfg.safety_distance * self.res
        if chk.in_obstacle is not None:
            i, tt = chk.in_obstacle
            return f"robot {i} enters an occupied cell at t = {tt:.2f} s"
        if chk.min_clearance is not None and chk.min_clearance < margin / 2:
            return f"a robot passes {chk.min_clearance:.4f} m from an occupied cell"
        if chk.min_separation < limit + margin - 1e-9:
            return (f"robots {chk.pair} come {chk.min_separation:.3f} m apart at t = {chk.time:.2f} s "
                    f"(safety distance {limit:g} m + {margin:g} m between samples)")
        return ""

    @staticmethod
    def _limits(trajs: list[PiecewisePolynomial]) -> tuple[float, float, float]:
        """Exact maxima of speed, acceleration and jerk over ``trajs``."""
        return tuple(float(max_derivative_norms(trajs, k).max()) for k in (1, 2, 3))

    def _plan_window(self, a: int, c: int, b: int, t: np.ndarray, committed: int, starts: list) -> tuple:
        """Plan steps a..b; steps a..committed-1 keep their durations in ``t``.

        Returns ``(trajectories, t, record)``, or ``(None, t, record)`` when the window
        could not be certified (the caller falls back or fails).
        """
        cfg = self.cfg
        rec = WindowRecord(a=a, c=c, b=b)
        att = _Attempt(alpha=1.0, samples_per_step=self.corridor_samples, corridor=cfg.corridor)
        repairs = limit_rounds = 0
        while True:
            t = t.copy()
            t[committed + 1:b + 1] = t[committed] + att.alpha * np.cumsum(self.dt[committed:b])
            # committed steps keep the corridor they were planned with (the previous
            # trajectory must stay a feasible point); new steps get the current one
            half = np.full(b - a, cfg.corridor * self.res)
            half[committed - a:] = att.corridor * self.res
            tic = time.perf_counter()
            trajs, problem = None, ""
            try:
                # every robot's problem has the same shape: one block-diagonal QP per window
                trajs = self._batch.solve([self._problem(i, a, b, t, att.samples_per_step, half, starts[i])
                                           for i in range(self.N)])
            except (InfeasibleError, SolverError) as e:
                problem = f"smoothing failed ({e})"
            rec.solve_s += time.perf_counter() - tic
            if trajs is not None:
                rec.check = self._check(trajs, float(t[a]), float(t[b]))
                problem = self._unsafe(rec.check)
            if not problem:
                v, acc, jerk = self._limits(trajs)
                # slowing a stretch by alpha scales v, a, j by alpha^-1, alpha^-2, alpha^-3
                over = max(v / cfg.v_max, math.sqrt(acc / cfg.a_max), (jerk / cfg.j_max) ** (1 / 3))
                if over <= 1.0 + 1e-9:
                    break
                limit_rounds += 1
                if committed >= b or limit_rounds > MAX_LIMIT_ROUNDS or att.alpha * over > MAX_ALPHA:
                    problem = (f"no timing meets v_max = {cfg.v_max:g} m/s, a_max = {cfg.a_max:g} m/s^2 and "
                               f"j_max = {cfg.j_max:g} m/s^3 (reached {v:.3g} m/s, {acc:.3g} m/s^2, {jerk:.3g} m/s^3 "
                               f"with steps {att.alpha:.3g} times slower)")
                    rec.repairs.append(problem)
                    return None, t, rec
                att.alpha *= over * 1.02
                continue
            repairs += 1
            if repairs > MAX_REPAIRS:
                rec.repairs.append(f"gave up: {problem}")
                return None, t, rec
            rec.repairs.append(self._repair(att, repairs, can_slow=committed < b))
            log.info("window %d..%d: %s -> %s", a, b, problem, rec.repairs[-1])
        rec.alpha, rec.samples_per_step, rec.corridor = att.alpha, att.samples_per_step, att.corridor
        return trajs, t, rec

    @staticmethod
    def _repair(att: _Attempt, attempt: int, can_slow: bool) -> str:
        """The next repair of a failing window; returns what it did."""
        if attempt <= 2 or not can_slow and attempt <= 4:
            att.samples_per_step *= 2
            return f"corridor samples x2 ({att.samples_per_step} per step)"
        if attempt == 3:
            att.corridor /= 2
            return f"corridor halved ({att.corridor:g} cell)"
        att.alpha *= 1.5
        return f"slower (x{att.alpha:.3g})"

    # ------------------------------------------------------------------ run
    def run(self, on_window: Callable[[WindowRecord], None] | None = None) -> ContinuousPlan:
        """Plan every window; returns the concatenated, checked trajectories."""
        N, T, cfg = self.N, self.T, self.cfg
        tic = time.perf_counter()
        if T == 0:  # nobody moved: hover in place for a moment
            hover = [PiecewisePolynomial([1.0], np.concatenate(
                [self.reference[0, i][None, None, :], np.zeros((1, cfg.degree, 2))], axis=1)) for i in range(N)]
            return ContinuousPlan(hover, np.array([0.0]), self.reference, self.kept, [], self._check(hover, 0.0, 1.0),
                                  0.0, 0.0, 0.0, self.unpruned, {"smoothing": 0.0})
        pieces: list[list[PiecewisePolynomial]] = [[] for _ in range(N)]
        t = np.zeros(T + 1)
        starts: list = ["rest"] * N
        records: list[WindowRecord] = []
        prev = None  # (trajectories, t, a, b) of the previous window, for continuous seams
        committed = 0  # steps < committed have fixed durations
        a = 0
        while a < T:
            c = min(a + self.E, T)
            b = c if cfg.seam == "rest" else min(a + cfg.horizon, T)
            trajs, t_new, rec = self._plan_window(a, c, b, t, max(a, committed), starts)
            if trajs is None:
                if prev is None or prev[3] <= a:
                    raise UnsafeTrajectoryError(f"steps {a}..{b}: {rec.repairs[-1]}; repairs tried: "
                                                f"{', '.join(rec.repairs[:-1]) or 'none'}")
                # fly the previous window's checked remainder to its end (at rest there)
                p_trajs, p_t, p_a, p_b = prev
                off = float(t[a] - p_t[p_a])
                for i in range(N):
                    pieces[i].append(p_trajs[i].restricted(off, p_trajs[i].duration))
                t[a:p_b + 1] = p_t[a:p_b + 1]
                rec.fallback, rec.c, rec.b = True, p_b, p_b
                records.append(rec)
                log.info("window %d..%d not certified: flying the previous plan to step %d", a, b, p_b)
                starts, prev, committed, a = ["rest"] * N, None, p_b, p_b
                if on_window is not None:
                    on_window(rec)
                continue
            t = t_new
            span = float(t[c] - t[a])
            for i in range(N):
                pieces[i].append(trajs[i] if c == b else trajs[i].restricted(0.0, span))
                if c < b:
                    state = np.stack([trajs[i].evaluate(span, derivative=k) for k in range(1, 4)])
                    starts[i] = (trajs[i].evaluate(span), state)
                else:
                    starts[i] = "rest"
            prev = (trajs, t.copy(), a, b) if c < b else None
            committed = b
            records.append(rec)
            if on_window is not None:
                on_window(rec)
            a = c
        smoothing_s = time.perf_counter() - tic
        window_check_s = self._check_s
        trajectories = [concatenate(p) for p in pieces]
        tic = time.perf_counter()
        check = self._check(trajectories, 0.0, trajectories[0].duration)
        problem = self._unsafe(check)
        if problem:  # each window passed; the whole must too (a bug otherwise, never a silent output)
            raise UnsafeTrajectoryError(f"assembled trajectories unsafe: {problem}")
        v, acc, jerk = self._limits(trajectories)
        check_s = time.perf_counter() - tic
        return ContinuousPlan(trajectories, t, self.reference, self.kept, records, check, v, acc, jerk, self.unpruned,
                              {"pruning": self.pruning_s, "smoothing": smoothing_s - window_check_s,
                               "checking": check_s + window_check_s})
