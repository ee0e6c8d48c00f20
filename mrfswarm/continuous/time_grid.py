"""The common time grid: nominal step durations and the durations at which a rest-to-rest flight is feasible.

Step j of the discrete plan is flown by every robot during :math:`[t_j, t_{j+1}]`. Its
nominal duration comes from the robots' own motion and the limits (:func:`motion_durations`:
each robot's speed profile along its moves, at most v_max, slowing for turns and waits;
the step lasts what its slowest mover needs), or, with a cruise ``speed`` given, from
the step's longest move (at least one cell) over that speed (:func:`nominal_durations`). The *witness* duration is long enough for every robot to fly its own discrete
move rest to rest (the degree-(2q-1) smooth step, all knot derivatives zero) with every
velocity, acceleration and jerk control point inside the limit polygons: that flight
satisfies every constraint of the window problem, so a window whose new steps last at
least this long always has a feasible point.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from mrfswarm.continuous.formulation import LIMIT_ORDERS, limit_polytope, piece_maps
from mrfswarm.trajectory.piece_stack import norms


def nominal_durations(paths: np.ndarray, resolution: float, speed: float, acceleration: float) -> np.ndarray:
    r"""(T,) nominal step durations: a trapezoidal speed profile along the steps' longest moves.

    Step j covers :math:`L_j` = its longest move (at least one cell, in metres); the
    swarm's nominal progress along :math:`s = \sum L_j` speeds up from rest at
    ``acceleration`` to ``speed``, cruises, and slows down to rest at the end (a triangle
    when the flight is too short to reach ``speed``). Step j lasts from the time the
    profile reaches :math:`s_j` to the time it reaches :math:`s_{j+1}`.
    """
    moves = norms(np.diff(np.asarray(paths, dtype=float), axis=0))  # (T, N)
    if moves.size == 0:
        return np.zeros(0)
    L = np.maximum(moves.max(axis=1), 1.0) * resolution
    s = np.concatenate([[0.0], np.cumsum(L)])
    total = s[-1]
    v = min(speed, float(np.sqrt(acceleration * total)))  # peak speed (a triangle if speed is not reached)
    ramp = v * v / (2 * acceleration)

    def time_at(x: np.ndarray) -> np.ndarray:
        up = np.sqrt(2 * np.minimum(x, ramp) / acceleration)
        cruise = np.clip(x - ramp, 0.0, total - 2 * ramp) / v
        down_dist = np.clip(x - (total - ramp), 0.0, ramp)
        down = (v - np.sqrt(np.maximum(v * v - 2 * acceleration * down_dist, 0.0))) / acceleration
        return up + cruise + down

    return np.diff(time_at(s))


def segment_times(length: np.ndarray, v0: np.ndarray, v1: np.ndarray, v_max: float | np.ndarray,
                  a: float) -> np.ndarray:
    r"""Shortest time to cover ``length`` from speed ``v0`` to ``v1`` with |acceleration| <= ``a``, speed <= ``v_max``.

    The trapezoid: up to the peak :math:`v_p = \min(v_{max}, \sqrt{aL + (v_0^2 + v_1^2)/2})`,
    cruise, down. ``v0``, ``v1`` must be reachable from each other within ``length``
    (the passes of :func:`motion_durations` make them so).
    """
    L = np.asarray(length, dtype=float)
    vp = np.minimum(v_max, np.sqrt(a * L + 0.5 * (v0 * v0 + v1 * v1)))
    vp = np.maximum(vp, np.maximum(v0, v1))
    d_up, d_down = (vp * vp - v0 * v0) / (2 * a), (vp * vp - v1 * v1) / (2 * a)
    cruise = np.maximum(L - d_up - d_down, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        t = (vp - v0) / a + (vp - v1) / a + np.where(vp > 0, cruise / np.where(vp > 0, vp, 1.0), 0.0)
    return np.where(L > 0, t, 0.0)


@lru_cache(maxsize=32)
def _rest_curve(v_max: float, a_max: float, j_max: float, samples: int = 4001) -> tuple[np.ndarray, np.ndarray]:
    """(t, s) of the fastest start from rest under the limits: jerk j_max until the acceleration reaches a_max,
    held until the speed is a jerk ramp short of v_max, then jerk -j_max to v_max at zero acceleration (a
    triangle of acceleration when a_max is not reached); ends when v_max is."""
    ramp = min(a_max / j_max, math.sqrt(v_max / j_max))  # time of each jerk ramp
    peak = j_max * ramp  # the acceleration reached
    hold = max(0.0, (v_max - peak * ramp) / peak)  # time at a_max
    t = np.linspace(0.0, 2 * ramp + hold, samples)
    acc = np.minimum.reduce([j_max * t, np.full_like(t, peak), j_max * (2 * ramp + hold - t)])
    v = np.concatenate([[0.0], np.cumsum(0.5 * (acc[1:] + acc[:-1]) * np.diff(t))])
    s = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t))])
    return t, s


def braking_distance(speed: float, a_max: float, j_max: float) -> float:
    """Metres of the shortest braking from ``speed`` to rest with acceleration <= a_max and jerk <= j_max (the
    fastest start from rest to ``speed``, backwards: :func:`_rest_curve`)."""
    return float(_rest_curve(float(speed), float(a_max), float(j_max))[1][-1])


def rest_times(distance: np.ndarray, v_max: float, a_max: float, j_max: float) -> np.ndarray:
    """The least time to cover ``distance`` (metres, any shape) from rest with speed <= v_max, acceleration <=
    a_max and jerk <= j_max (the end speed free): the fastest start (:func:`_rest_curve`), then cruise at v_max.
    Braking to rest over a distance takes as long, backwards."""
    t, s = _rest_curve(float(v_max), float(a_max), float(j_max))
    d = np.asarray(distance, dtype=float)
    return np.where(d <= s[-1], np.interp(d, s, t), t[-1] + (d - s[-1]) / v_max)


def reachable_speed(distance: float, v_max: float, a_max: float, j_max: float) -> float:
    """The top speed of the fastest move from rest to rest over ``distance`` metres under the limits.

    Half the way speeds up, half brakes: the top speed v is the one whose fastest start from rest to v at zero
    acceleration (:func:`_rest_curve` with v_max = v) covers ``distance / 2``: :math:`v^{3/2}/\\sqrt{j}` while
    a_max is not reached (v <= a^2 / j), else :math:`v (a/j + v/a) / 2`; v_max where that is higher.
    """
    a, j, half = float(a_max), float(j_max), 0.5 * float(distance)
    v = (half * math.sqrt(j)) ** (2.0 / 3.0)
    if v > a * a / j:
        v = 0.5 * (-a * a / j + math.sqrt((a * a / j) ** 2 + 8.0 * a * half))
    return float(min(v, v_max))


@dataclass(frozen=True)
class SwarmProfile:
    """The speed profile of the swarm's progress over the steps (see :func:`motion_profile`).

    Attributes
    ----------
    ell
        (T,) the swarm's progress per step: its longest move, at least one cell (metres).
    cap
        (T,) the speed cap of each step: ``ell`` over the time its slowest mover needs.
    need
        (T,) the time each step's slowest mover needs on its own profile.
    knots
        (T + 1,) the profile's speed at every step, at rest at both ends.
    acceleration
        The profile's acceleration.
    limits
        (v_max, a_max, j_max) or None: with them, the steps before a window's stop at a step b short of the
        flight's end last at least what the fastest jerk-limited stop needs over the swarm's progress to b
        (:func:`rest_times`, backwards). The trapezoids at ``acceleration`` do not see the jerk limit: the bold
        profile (twice the jerk-limited average) brakes in half the time a robot at cruise can, and the window QP,
        which keeps the robots in their regions rather than on the profile, slows the flown steps to make the stop.
        Measured (flight-quality cases, 2026-11-27, one run each, against the trapezoids alone): clutter40 90.2 s
        -> 74.3 of makespan (12 s of planning instead of 25), forest 31.4 -> 27.5, rooms 30.4 -> 28.7, aisles30
        42.8 -> 41.4, open50 36.6 -> 36.0, trap 25.9 -> 26.1, cross300 66.6 -> 67.0, the corridor, doorway and arena
        the same. The bold attempt's tail braking as the moderate profile instead: clutter40 87.5, forest 29.4.
        With that tail, the floor on the flight's last stop too (the steps it flies) cost the doorway 3 % (12.95 ->
        13.34) and the trap 2 %; on the start from rest as well (robots may lag their cells, which the floor
        ignores), the corridor 21.2 against 20.7, the doorway 13.7, the arena 7.24 against 6.88.
    """

    ell: np.ndarray
    cap: np.ndarray
    need: np.ndarray
    knots: np.ndarray
    acceleration: float
    limits: tuple[float, float, float] | None = None

    @property
    def durations(self) -> np.ndarray:
        """(T,) the whole flight's step durations."""
        return self.window(0, len(self.ell), rest_at_end=True)

    def window(self, a: int, b: int, rest_at_end: bool = True) -> np.ndarray:
        """(b - a,) durations of steps a..b-1 for a window that starts at the profile's speed at step a and,
        with ``rest_at_end``, brakes to rest at step b (a window of the receding horizon ends at rest)."""
        u = self.knots[a:b + 1].copy()
        if rest_at_end:
            u[-1] = 0.0
        _passes(u, self.ell[a:b], self.acceleration)
        out = np.maximum(self.need[a:b], segment_times(self.ell[a:b], u[:-1], u[1:], self.cap[a:b],
                                                       self.acceleration))
        if self.limits is not None and rest_at_end and b < len(self.ell):
            # a window's stop at b, which it plans and does not fly: no faster than the jerk limit allows
            t = rest_times(np.concatenate([np.cumsum(self.ell[a:b][::-1])[::-1], [0.0]]), *self.limits)
            out = np.maximum(out, -np.diff(t))
        return out


def _passes(u: np.ndarray, ell: np.ndarray, a: float) -> None:
    """Knot speeds ``u`` (T + 1, ...) (in place) reachable from each other over the steps ``ell`` (T, ...) at
    acceleration ``a``: the forward pass u[k + 1] = min(u[k + 1], sqrt(u[k]^2 + 2 a ell[k])), then the backward
    one, each a running minimum in the squared speeds, w[k] = S[k] + min over j <= k of (u[j]^2 - S[j]) with S
    the running sum of 2 a ell."""
    inc = 2 * a * np.asarray(ell, dtype=float)
    zero = np.zeros_like(inc[:1])
    S = np.concatenate([zero, np.cumsum(inc, axis=0)])
    w = S + np.minimum.accumulate(u * u - S, axis=0)
    R = np.concatenate([zero, np.cumsum(inc[::-1], axis=0)])  # the same from the end
    w = (R + np.minimum.accumulate(w[::-1] - R, axis=0))[::-1]
    u[...] = np.sqrt(np.maximum(w, 0.0))


def motion_durations(paths: np.ndarray, resolution: float, v_max: float, acceleration: float) -> np.ndarray:
    """(T,) step durations of the whole flight from :func:`motion_profile`."""
    if len(paths) < 2:
        return np.zeros(0)
    return motion_profile(paths, resolution, v_max, acceleration).durations


def robot_needs(paths: np.ndarray, resolution: float, v_max: float, acceleration: float,
                drift: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    r"""(T, N) the time each robot's move needs on its own speed profile, and (T, N) the moves' lengths (metres).

    Each robot flies its discrete polyline with a speed profile of its own: at most
    ``v_max``, speeding up and slowing down at ``acceleration``, at rest where it waits
    (a step without a move) and at both ends (except that with ``drift`` > 0 a single-step
    wait between two moves that turn by less than 90 degrees counts as a move of ``drift``
    metres along the way: the robot slows down within its cell instead of stopping), and
    through a turn of angle
    :math:`	heta` between two moves no faster than
    :math:`\sqrt{a L / (2 \sin(	heta/2))}` (the speed whose change of direction,
    :math:`2 v \sin(	heta/2)`, takes the time of half a move each side at ``acceleration``).
    Forward and backward passes make the knot speeds reachable (the classic
    velocity-profile recursion); a move then takes its trapezoid's time
    (:func:`segment_times`).
    """
    P = np.asarray(paths, dtype=float) * resolution
    m = np.diff(P, axis=0)  # (T, N, d)
    if drift > 0 and len(m) >= 3:
        m = _drift_through_waits(m, drift)
    L = np.linalg.norm(m, axis=-1)  # (T, N)
    T = len(L)
    a = float(acceleration)
    # knot speed limits (T + 1, N): rest at the ends and next to a wait
    cap = np.full((T + 1, len(L[0])), float(v_max))
    cap[0] = cap[-1] = 0.0
    cos = (m[:-1] * m[1:]).sum(-1) / np.maximum(L[:-1] * L[1:], 1e-12)
    half = np.sqrt(np.clip((1 - cos) / 2, 0.0, 1.0))  # sin(theta / 2)
    with np.errstate(divide="ignore"):
        turn = np.sqrt(a * np.minimum(L[:-1], L[1:]) / np.maximum(2 * half, 1e-12))
    cap[1:-1] = np.minimum(cap[1:-1], turn)
    v = cap.copy()
    _passes(v, L, a)  # forward: reachable from the previous knot; backward: the next knot reachable from it
    return segment_times(L, v[:-1], v[1:], v_max, a), L


def next_moves(moves: np.ndarray) -> np.ndarray:
    """(T, N) for each step of moves (T, N, d), the first step at or after it where the robot moves (T if none)."""
    T = len(moves)
    moving = np.linalg.norm(moves, axis=-1) > 0
    return np.minimum.accumulate(np.where(moving, np.arange(T)[:, None], T)[::-1], axis=0)[::-1]


def drift_waits(moves: np.ndarray, longest: int = 1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The waits a robot can drift through instead of stopping, in moves (T, N, d).

    A wait is one if it is in a run of at most ``longest`` waits between two moves that turn
    by less than 90 degrees. Returns (T, N) bool, those waits; (T, N, d) the unit
    direction of the way through each (the sum of the moves before and after it; zero elsewhere);
    (T, N) the length of its run (0 elsewhere).
    """
    m = np.asarray(moves, dtype=float)
    T = len(m)
    moving = np.linalg.norm(m, axis=-1) > 0  # (T, N)
    prev = np.maximum.accumulate(np.where(moving, np.arange(T)[:, None], -1), axis=0)  # last move at or before k
    nxt = next_moves(m)
    waits = np.zeros(m.shape[:2], dtype=bool)
    way = np.zeros_like(m)
    runs = np.zeros(m.shape[:2], dtype=np.int64)
    k, i = np.nonzero(~moving & (prev >= 0) & (nxt < T))
    before, after = m[prev[k, i], i], m[nxt[k, i], i]
    w = nxt[k, i] - prev[k, i] - 1
    ok = ((before * after).sum(-1) > 0) & (w <= longest)
    k, i, through = k[ok], i[ok], (before + after)[ok]
    waits[k, i] = True
    way[k, i] = through / np.linalg.norm(through, axis=-1, keepdims=True)
    runs[k, i] = w[ok]
    return waits, way, runs


def _drift_through_waits(m: np.ndarray, drift: float) -> np.ndarray:
    """Moves ``m`` (T, N, d) with the single-step waits of :func:`drift_waits` replaced by moves of ``drift``
    metres along the way (see :func:`robot_needs`)."""
    waits, way, runs = drift_waits(m)
    if not waits.any():
        return m
    out = m.copy()
    out[waits] = (drift / runs[waits])[:, None] * way[waits]
    return out


def lead_needs(needs: np.ndarray, slack: np.ndarray | float) -> np.ndarray:
    """(T,) the shortest step durations at which every robot flies every stretch of its steps on its own profile,
    leading or lagging its knots by up to ``slack`` seconds of it.

    ``needs`` (T, N): each robot's time per step (:func:`robot_needs`); ``slack``: (T + 1,) seconds per knot, or
    one value for every inner knot (none at the flight's ends). A robot flies its polyline at its own pace and
    passes each knot within ``slack`` of the time it would there, so the knot times tau must meet
    ``tau_b - tau_a >= C_b - C_a - s_a - s_b`` for every robot and every stretch a..b (C its cumulative needs).
    The earliest such times, knot by knot, are the longest paths of these difference constraints. With no slack
    a step lasts its slowest mover's need, as :func:`motion_profile`'s; with it a robot's long move (a diagonal
    merge between straight steps of a file) borrows time from the steps around it.
    """
    needs = np.asarray(needs, dtype=float)
    T, N = needs.shape
    s = np.asarray(slack, dtype=float)
    if s.ndim == 0:
        s = np.concatenate([[0.0], np.full(max(T - 1, 0), float(s)), [0.0]]) if T else np.zeros(1)
    if s.shape != (T + 1,):
        raise ValueError(f"slack: expected one value or {T + 1} (one per knot), got shape {s.shape}")
    C = np.concatenate([np.zeros((1, N)), np.cumsum(needs, axis=0)])
    tau = np.zeros(T + 1)
    best = -C[0] - s[0]  # per robot: the latest tau_a - C_a - s_a so far
    for k in range(1, T + 1):
        tau[k] = max(tau[k - 1], float(np.max(C[k] + best, initial=-np.inf)) - s[k])
        best = np.maximum(best, tau[k] - C[k] - s[k])
    return np.diff(tau)


def motion_profile(paths: np.ndarray, resolution: float, v_max: float, acceleration: float,
                   drift: float = 0.0, limits: tuple[float, float, float] | None = None,
                   lead: np.ndarray | float = 0.0) -> SwarmProfile:
    """(T,) step durations derived from every robot's own motion and the limits (:func:`robot_needs`, then
    :func:`swarm_profile`).

    All robots share the time grid, so a step lasts the longest time any robot's move
    needs: a straight run flies at ``v_max``, a turn or a wait slows only the steps around it.
    With ``lead`` (metres a robot may be ahead of or behind its cell at a knot: one for every inner knot, or
    (T + 1,)), a step lasts what :func:`lead_needs` leaves of it, and the swarm's progress in it is what
    ``v_max`` covers in that time (at least a cell).
    """
    needs, L = robot_needs(paths, resolution, v_max, acceleration, drift)
    longest = L.max(axis=1, initial=0.0)
    if np.any(np.asarray(lead) > 0) and len(needs):
        need = lead_needs(needs, np.asarray(lead, dtype=float) / v_max)
        return swarm_profile(need, np.maximum(np.minimum(longest, v_max * need), resolution), v_max, acceleration,
                             limits)
    return swarm_profile(needs.max(axis=1, initial=0.0), np.maximum(longest, resolution), v_max, acceleration, limits)


def swarm_profile(need: np.ndarray, ell: np.ndarray, v_max: float, acceleration: float,
                  limits: tuple[float, float, float] | None = None) -> SwarmProfile:
    """The swarm's profile from each step's slowest mover's need (T,) and the steps' progress ``ell`` (T,)."""
    t, a = need, float(acceleration)
    # The steps share one grid: a robot on a straight run flies each step's move in the step's duration, so
    # the durations themselves must change no faster than a speed profile can (a long step between short
    # ones would brake and re-accelerate every robot in it). One more profile, of the swarm's progress ell_j
    # per step at the step speed ell_j / t_j, smooths them.
    s = np.minimum(v_max, ell / np.maximum(t, 1e-12))
    u = np.minimum(np.concatenate([[0.0], s]), np.concatenate([s, [0.0]]))
    _passes(u, ell, a)
    return SwarmProfile(ell=ell, cap=s, need=t, knots=u, acceleration=a, limits=limits)


@dataclass(frozen=True)
class FlightModel:
    """The time grid's first profile as the flight time of discrete paths (:mod:`mrfswarm.discrete.merge_waits`
    asks it whether a change of the paths' timing shortens the flight)."""

    resolution: float
    v_max: float
    acceleration: float
    drift: float = 0.0

    def needs(self, paths: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(T, n) each robot's need and (T, n) its moves' lengths, for paths (T + 1, n, d) cells."""
        return robot_needs(paths, self.resolution, self.v_max, self.acceleration, self.drift)

    def duration(self, need: np.ndarray, longest: np.ndarray) -> float:
        """The flight's duration from each step's largest need and longest move (T,) each."""
        ell = np.maximum(longest, self.resolution)
        return float(swarm_profile(need, ell, self.v_max, self.acceleration).durations.sum())


@lru_cache(maxsize=16)
def rest_step_peaks(degree: int, derivative: int) -> tuple[float, ...]:
    """Largest control-point norm of derivatives 1, 2, 3 of a unit rest-to-rest step of unit duration."""
    pm = piece_maps(degree, derivative)
    k = pm.evaluate(np.array([1.0]))
    z = np.zeros(pm.nz)
    z[pm.derivative] = 1.0  # the position at tau = 1; every other knot derivative (and bubble) is 0
    peaks = []
    for r in LIMIT_ORDERS:
        rows = pm.rows[r]
        K = k[pm.k_offset[r]:pm.k_offset[r] + rows * pm.nz].reshape(pm.nz, rows).T
        peaks.append(float(np.abs(K @ z).max()))
    return tuple(peaks)


def witness_durations(paths: np.ndarray, resolution: float, limits: tuple[float, float, float], degree: int,
                      derivative: int, margin: float = 1e-6) -> np.ndarray:
    """(T,) durations at which every robot's rest-to-rest move meets the limits by its control points.

    A move of length L flown in time T has r-th derivative control points of norm
    ``peak_r L / T^r``, all along the move; each must fit in the limit polytope
    (:func:`~mrfswarm.continuous.formulation.limit_polytope`: the 16-gon in the plane),
    within its inner radius ``rho limit_r (1 - margin)``.
    """
    inner = limit_polytope(np.shape(paths)[-1])[1]
    moves = norms(np.diff(np.asarray(paths, dtype=float), axis=0))
    L = moves.max(axis=1, initial=0.0) * resolution
    out = np.zeros_like(L)
    for r, peak, lim in zip(LIMIT_ORDERS, rest_step_peaks(degree, derivative), limits):
        out = np.maximum(out, (peak * L / (inner * lim * (1 - margin))) ** (1.0 / r))
    return out * (1 + 1e-6)
