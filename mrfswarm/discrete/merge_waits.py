"""Merging a robot's waits: the same cells in the same order, fewer stops and starts (``mrf.merge_waits``).

The MRF steps move every robot at once, and a robot blocked for a step waits where it
is: its path comes out as runs of moves cut by single waits (move, wait, move, wait...).
Flown on the common time grid each run starts from rest and ends at rest, and a step
lasts as long as its slowest mover needs, so a step where any robot starts or stops is
a slow step (about 0.9 s for a cell from rest against 0.5 s at 2 m/s on the default
limits). In a 78-step plan of 40 robots on a 64 x 64 clutter map, 60 steps were paced by a robot
starting or stopping.

After the MRF has chosen the paths, :func:`merge_waits` moves each wait that separates
two runs of a robot to the run's other end, where it joins another wait: the earlier
run is delayed by the wait's length (its moves happen later), or if that is not safe
the later run is advanced (its moves happen sooner). Each robot keeps its cells, their
order and its start and end; only when it is in them changes. A change is kept only if
the robot stays at least one cell (in the downwash-scaled metric) from every other robot
during every step it touches, the invariant of :mod:`mrfswarm.discrete.safety`, which is
checked again on the whole plan afterwards; the moves are the MRF's own moves, so their
clearance from obstacles is unchanged. In that plan the runs went from 139 to 85.

Fewer runs is not always a shorter flight: a robot that waited mid-flight together with
another shares its slow steps with it, and a merge can move its start to a step where
everyone else cruises. So, given the time grid's model of the flight (the pipeline
passes the moderate profile of :mod:`mrfswarm.continuous.time_grid` when the continuous
stage is on), a merge is kept only if the model's flight time does not grow. Measured
(flight_quality bench, makespan over the bound, no merging -> every safe merge -> merges
the model keeps): doorway 1.57 -> 1.61 -> 1.56, clutter40 2.74 -> 2.42 -> 2.45, aisles30
1.77 -> 1.69 -> 1.68; forest went 1.73 -> 1.80 either way (its windows fly slower
profiles than the model's where the merged runs meet).

This is a post-process of the paper's method (its robots keep the MRF's timing);
``mrf.merge_waits = false`` turns it off, as the paper's scenario configs do.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from mrfswarm.discrete.motion import MIN_SEPARATION, min_distance_during_move
from mrfswarm.geometry import downwash_scale

_TOL = 1e-9
#: Sweeps over all robots; a merge can make another one possible (measured: the third finds none on clutter40).
PASSES = 4
#: Steps per block of :func:`robot_clear`'s first filter (cross1000 merges: 2, 3, 4, 8 steps took 12.8, 11.5, 17.8, 43.9 s).
BLOCK = 3


def robot_clear(paths: np.ndarray, robot: int, first: int, last: int, scale: np.ndarray,
                own: np.ndarray | None = None, largest_move: float | None = None) -> bool:
    """Robot ``robot`` stays MIN_SEPARATION (scaled by ``scale``) from every other robot in steps first..last - 1,
    flying its column of ``paths`` or, given, ``own`` (T + 1, d) instead.

    Exact, and local: during a step two robots' Chebyshev gap shrinks by at most the
    largest component of each one's move, and the Euclidean distance is at least that gap.
    So the span is cut into blocks of :data:`BLOCK` steps; a robot is a candidate for a
    block if its gap at the block's first step is within MIN_SEPARATION plus what both can
    move in the block (``largest_move`` bounds any robot's move per axis, computed from
    ``paths`` when not given), and of the candidates only the (step, robot) pairs whose
    gap at the step's start is within MIN_SEPARATION plus both moves of that step are
    tested. A 1000-robot crossing spent 47 s of 323 here when every robot the span's whole
    motion could bring near was tested on every step.
    """
    if last <= first:
        return True
    seg = paths[first:last + 1]  # (S + 1, N, d)
    mine = (seg[:, robot] if own is None else own[first:last + 1]) * scale  # (S + 1, d)
    S = len(seg) - 1
    if largest_move is None:
        largest_move = float(np.abs(np.diff(seg.reshape(S + 1, -1), axis=0)).max())
    mine_step = _largest(np.abs(np.diff(mine, axis=0)))  # (S,)
    starts = np.arange(0, S, BLOCK)
    within = np.add.reduceat(mine_step, starts) + largest_move * float(scale.max()) * np.diff(np.append(starts, S))
    gap = _largest(np.abs(seg[starts] * scale - mine[starts, None]))  # (blocks, N)
    gap[:, robot] = np.inf
    blk, j = np.nonzero(gap <= MIN_SEPARATION + within[:, None] + _TOL)
    if not len(blk):
        return True
    s = (starts[blk, None] + np.arange(BLOCK)).ravel()  # every step of each candidate's block
    j = np.repeat(j, BLOCK)
    keep = s < S
    s, j = s[keep], j[keep]
    p0, p1 = seg[s, j] * scale, seg[s + 1, j] * scale
    d0 = mine[s] - p0
    close = _largest(np.abs(d0)) < MIN_SEPARATION + _largest(np.abs(p1 - p0)) + mine_step[s] + _TOL
    if not close.any():
        return True
    s, d0 = s[close], d0[close]
    v = (mine[s + 1] - mine[s]) - (p1[close] - p0[close])
    return bool(np.all(min_distance_during_move(d0, v) >= MIN_SEPARATION - _TOL))


def _largest(a: np.ndarray) -> np.ndarray:
    """Largest of the last axis's 2 or 3 components (a reduction over so short an axis is slow in numpy)."""
    out = np.maximum(a[..., 0], a[..., 1])
    return out if a.shape[-1] == 2 else np.maximum(out, a[..., 2])


class FlightTime(Protocol):
    """How long the paths take to fly (``mrfswarm.continuous.time_grid.FlightModel``)."""

    def needs(self, paths: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(T, n) each robot's need (s) and (T, n) its moves' lengths for paths (T + 1, n, d)."""

    def duration(self, need: np.ndarray, longest: np.ndarray) -> float:
        """The flight's duration from each step's largest need and longest move (T,)."""


class _Steps:
    """Each step's largest need and longest move over the robots, and the same without any one robot."""

    def __init__(self, needs: np.ndarray, lengths: np.ndarray) -> None:
        self.needs, self.lengths = needs, lengths
        self._top()

    def _top(self) -> None:
        self.top = []
        for A in (self.needs, self.lengths):
            if A.shape[1] < 2:
                first, second, arg = A.max(axis=1), np.zeros(len(A)), np.zeros(len(A), dtype=np.intp)
            else:
                idx = np.argpartition(-A, 1, axis=1)[:, :2]
                vals = np.take_along_axis(A, idx, axis=1)
                arg = np.where(vals[:, 1] > vals[:, 0], idx[:, 1], idx[:, 0])
                first, second = vals.max(axis=1), vals.min(axis=1)
            self.top.append((first, second, arg))

    def without(self, robot: int) -> tuple[np.ndarray, np.ndarray]:
        """(T,) each step's largest need and longest move over the robots but ``robot``."""
        (f1, s1, a1), (f2, s2, a2) = self.top
        return np.where(a1 == robot, s1, f1), np.where(a2 == robot, s2, f2)

    def set(self, robot: int, needs: np.ndarray, lengths: np.ndarray) -> None:
        self.needs[:, robot], self.lengths[:, robot] = needs, lengths
        self._top()


def merge_waits(paths: np.ndarray, downwash: float = 1.0,
                flight: FlightTime | None = None) -> tuple[np.ndarray, int]:
    """The (T + 1, N, d) ``paths`` with every wait between two runs of moves merged where safe, and the merges.

    See the module docstring. The result has the same steps, starts and ends, and each
    robot visits the same cells in the same order. With ``flight`` a merge is kept only if
    it does not lengthen the flight by that model.
    """
    P = np.array(paths, dtype=np.int64)
    T, N = len(P) - 1, P.shape[1]
    if T < 3:
        return P, 0
    scale = downwash_scale(P.shape[-1], downwash)
    # a merge re-times a robot's own moves, so the largest move of the plan stays what it is
    largest_move = float(np.abs(np.diff(P, axis=0)).max())
    steps = None if flight is None else _Steps(*flight.needs(P))
    total = np.inf if steps is None or flight is None else flight.duration(steps.needs.max(axis=1),
                                                                            steps.lengths.max(axis=1))
    merged = 0
    for _ in range(PASSES):
        before = merged
        for i in range(N):
            k = 1
            moves = np.any(P[1:, i] != P[:-1, i], axis=1)  # again after each merge of this robot
            while k < T:
                if moves[k] or not moves[k - 1]:
                    k += 1
                    continue
                e = k  # the waits [k, e) follow a move and ...
                while e < T and not moves[e]:
                    e += 1
                if e == T:  # ... end the flight: nothing to merge
                    break
                w, s, r = e - k, k, e
                while s > 0 and moves[s - 1]:  # the run before: [s, k)
                    s -= 1
                while r < T and moves[r]:  # the run after: [e, r)
                    r += 1
                late = P[:, i].copy()  # the run before delayed by w
                late[s:s + w + 1] = P[s, i]
                late[s + w:e + 1] = P[s:k + 1, i]
                soon = P[:, i].copy()  # the run after advanced by w
                soon[k:k + (r - e) + 1] = P[e:r + 1, i]
                soon[k + (r - e):r + 1] = P[r, i]
                for col, f0, f1 in ((late, s, e), (soon, k, r)):
                    if not robot_clear(P, i, f0, f1, scale, col, largest_move):
                        continue
                    if steps is not None and flight is not None:
                        need_i, len_i = flight.needs(col[:, None])
                        need, longest = steps.without(i)
                        t = flight.duration(np.maximum(need, need_i[:, 0]), np.maximum(longest, len_i[:, 0]))
                        if t > total + 1e-9:
                            continue
                        steps.set(i, need_i[:, 0], len_i[:, 0])
                        total = t
                    P[:, i] = col
                    moves = np.any(P[1:, i] != P[:-1, i], axis=1)
                    merged += 1
                    break
                k = e + 1
        if merged == before:
            break
    return P, merged
