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

from collections.abc import Iterator
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
                own: np.ndarray | None = None, largest_move: float | None = None,
                index: CellIndex | None = None) -> bool:
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

    Given ``index`` (a :class:`CellIndex` of ``paths``; ``scale`` positive on x and y), the
    same pairs are found from the other end: the index gives, for each step, the robots whose
    cells then lie within MIN_SEPARATION plus ``largest_move`` plus the robot's own move on x
    and on y, which holds every robot the step's test keeps, and of these the pairs both tests
    keep are tested: the same pairs, in another order, and the same answer (on a 1000-robot
    crossing's merges the block test kept 36 M (step, robot) pairs for the step test's 25 M,
    after measuring the gap to every robot at every block's start). The first block is tested
    before the others: that crossing's merge_waits refused 96 % of the merges it tried, 95 %
    of those in their first block.
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

    def clear(b0: int, b1: int) -> bool:
        """The pairs of blocks b0..b1 - 1 (steps starts[b0] .. starts[b1] - 1)."""
        if b0 >= b1:
            return True
        if index is None:
            gap = _largest(np.abs(seg[starts[b0:b1]] * scale - mine[starts[b0:b1], None]))  # (blocks, N)
            gap[:, robot] = np.inf
            blk, j = np.nonzero(gap <= MIN_SEPARATION + within[b0:b1, None] + _TOL)
            s = (starts[b0 + blk, None] + np.arange(BLOCK)).ravel()  # every step of each candidate's block
            j = np.repeat(j, BLOCK)
            keep = s < S
            s, j = s[keep], j[keep]
        else:
            steps = np.arange(b0 * BLOCK, min(b1 * BLOCK, S))
            reach = MIN_SEPARATION + largest_move * float(scale.max()) + mine_step[steps] + _TOL
            q, j = index.near(first + steps, mine[steps], reach, scale)
            keep = j != robot
            s, j = steps[q[keep]], j[keep]
        p0, p1 = seg[s, j] * scale, seg[s + 1, j] * scale
        d0 = mine[s] - p0
        close = _largest(np.abs(d0)) < MIN_SEPARATION + _largest(np.abs(p1 - p0)) + mine_step[s] + _TOL
        if index is not None:  # and the block test, as above
            at = np.flatnonzero(close)
            blk = s[at] // BLOCK
            gap = _largest(np.abs(seg[starts[blk], j[at]] * scale - mine[starts[blk]]))
            close[at] = gap <= (MIN_SEPARATION + within + _TOL)[blk]
        if not close.any():
            return True
        s, d0 = s[close], d0[close]
        v = (mine[s + 1] - mine[s]) - (p1[close] - p0[close])
        return bool(np.all(min_distance_during_move(d0, v) >= MIN_SEPARATION - _TOL))

    # most refused merges meet another robot in their first block (see above)
    return clear(0, 1) and clear(1, len(starts))


def _largest(a: np.ndarray) -> np.ndarray:
    """Largest of the last axis's 2 or 3 components (a reduction over so short an axis is slow in numpy)."""
    out = np.maximum(a[..., 0], a[..., 1])
    return out if a.shape[-1] == 2 else np.maximum(out, a[..., 2])


def waits_clear(paths: np.ndarray, robot: int, cells: np.ndarray, steps: np.ndarray, scale: np.ndarray,
                largest_move: float, index: CellIndex) -> np.ndarray:
    """(Q,) whether robot ``robot`` waiting at ``cells[q]`` (Q, d) through step ``steps[q]`` (to steps[q] + 1) stays
    MIN_SEPARATION (scaled by ``scale``) from every other robot of ``paths``; ``index`` a :class:`CellIndex` of them.

    :func:`robot_clear` of a robot that waits at one cell c through steps first..last is these
    tests' conjunction over first..last - 1, made at once for many cells and steps: its filters
    leave out only pairs that are clear (a gap to c beyond MIN_SEPARATION plus the other's
    move), and the pairs it keeps are tested here with the same arithmetic (its own move 0).
    """
    mine = cells * scale  # (Q, d)
    reach = np.full(len(steps), MIN_SEPARATION + largest_move * float(scale.max()) + _TOL)
    q, j = index.near(steps, mine, reach, scale)
    keep = j != robot
    q, j = q[keep], j[keep]
    p0, p1 = paths[steps[q], j] * scale, paths[steps[q] + 1, j] * scale
    d0 = mine[q] - p0
    close = _largest(np.abs(d0)) < MIN_SEPARATION + _largest(np.abs(p1 - p0)) + _TOL
    q, d0 = q[close], d0[close]
    v = (mine[q] - mine[q]) - (p1[close] - p0[close])
    ok = np.ones(len(steps), dtype=bool)
    ok[q[min_distance_during_move(d0, v) < MIN_SEPARATION - _TOL]] = False
    return ok


class CellIndex:
    """Each step's robots sorted by cell, x then y: the robots whose cells lie in a box at a step, found
    without looking at the others (:func:`robot_clear`).

    One int64 key per step t and robot j at cell (x, y, ...), ``((t X + x') Y + y') N + j``, with
    x', y' counted from the plan's smallest x and y and X, Y the lengths of their ranges. Each
    step's N keys are kept sorted, so all (T + 1) N keys are sorted and a box at a step is one
    range of keys per x. Built in O(T N log N); a robot's changed cells are moved in O(N) per step
    from its first changed step to its last.
    The cells must stay within the plan's ranges of x and y, as they do when a merge re-times them.
    """

    def __init__(self, paths: np.ndarray) -> None:
        P = np.asarray(paths)
        if not np.issubdtype(P.dtype, np.integer):
            raise TypeError(f"CellIndex: paths must be integer cells, got {P.dtype}")
        self.n = P.shape[1]
        self.low = P[..., :2].min(axis=(0, 1)).astype(np.int64)
        self.size = P[..., :2].max(axis=(0, 1)).astype(np.int64) - self.low + 1
        self.keys = np.sort(self._key(np.arange(len(P))[:, None], P[..., :2], np.arange(self.n)), axis=1)
        self._flat = self.keys.reshape(-1)  # a view: moves update both

    def _key(self, step: np.ndarray | int, cell: np.ndarray, robot: np.ndarray | int) -> np.ndarray:
        c = cell[..., :2].astype(np.int64) - self.low
        return ((step * self.size[0] + c[..., 0]) * self.size[1] + c[..., 1]) * self.n + robot

    def move(self, robot: int, old: np.ndarray, new: np.ndarray) -> None:
        """Robot ``robot``'s column of the plan goes from ``old`` to ``new`` (T + 1, d) cells."""
        rows = np.flatnonzero(np.any(old[:, :2] != new[:, :2], axis=1))
        if not len(rows):
            return
        if np.any(new[rows, :2] < self.low) or np.any(new[rows, :2] >= self.low + self.size):
            raise ValueError("CellIndex: a cell outside the indexed plan's x and y")
        # a step's keys stay between the step's bounds, so the steps from the first to the last changed one are
        # sorted again by taking the old keys out and putting the new ones in, all at once
        part = self._flat[rows[0] * self.n:(rows[-1] + 1) * self.n]
        kept = np.delete(part, np.searchsorted(part, self._key(rows, old[rows], robot)))
        add = self._key(rows, new[rows], robot)
        part[:] = np.insert(kept, np.searchsorted(kept, add), add)

    def near(self, steps: np.ndarray, centre: np.ndarray, reach: np.ndarray,
             scale: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(query, robot) pairs, query q at step ``steps[q]``: every robot whose cell c there has
        ``|c_k scale_k - centre[q, k]| <= reach[q]`` on x and y (and maybe one that misses by a hair).

        The bounds are widened by a millionth of the coordinates' size, so float rounding cannot drop a cell.
        """
        c, half = centre[:, :2] / scale[:2], reach[:, None] / scale[:2]
        wide = half + 1e-6 * (1.0 + np.abs(c) + half)
        # clipped as floats first: a far centre must not overflow the integers
        lo = np.clip(np.ceil(c - wide) - self.low, 0, self.size).astype(np.int64)
        hi = np.clip(np.floor(c + wide) - self.low, -1, self.size - 1).astype(np.int64)
        nx = np.maximum(hi[:, 0] - lo[:, 0] + 1, 0)
        b = np.repeat(np.arange(len(steps)), nx)
        x = lo[b, 0] + np.arange(len(b)) - np.repeat(np.cumsum(nx) - nx, nx)
        base = (steps[b] * self.size[0] + x) * self.size[1]
        start = np.searchsorted(self._flat, (base + lo[b, 1]) * self.n)
        count = np.maximum(np.searchsorted(self._flat, (base + hi[b, 1] + 1) * self.n) - start, 0)
        at = np.repeat(start - (np.cumsum(count) - count), count) + np.arange(int(count.sum()))
        return np.repeat(b, count), self._flat[at] % self.n


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
        self.top = [_top_two(A) for A in (needs, lengths)]

    def without(self, robot: int) -> tuple[np.ndarray, np.ndarray]:
        """(T,) each step's largest need and longest move over the robots but ``robot``."""
        (f1, s1, a1), (f2, s2, a2) = self.top
        return np.where(a1 == robot, s1, f1), np.where(a2 == robot, s2, f2)

    def set(self, robot: int, needs: np.ndarray, lengths: np.ndarray) -> None:
        # only the steps whose values change are ranked again (all of them took 2 s of a 1000-robot crossing's 25)
        rows = np.flatnonzero((self.needs[:, robot] != needs) | (self.lengths[:, robot] != lengths))
        self.needs[:, robot], self.lengths[:, robot] = needs, lengths
        for A, top in zip((self.needs, self.lengths), self.top):
            for old, new in zip(top, _top_two(A[rows])):
                old[rows] = new


def _top_two(A: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(T,) each row's largest value, second largest (0 with one column) and a column holding the largest.

    Which column, where two hold it, does not matter: :meth:`_Steps.without` then gives the same value either way.
    """
    if A.shape[1] < 2:
        return A.max(axis=1), np.zeros(len(A)), np.zeros(len(A), dtype=np.intp)
    idx = np.argpartition(-A, 1, axis=1)[:, :2]
    vals = np.take_along_axis(A, idx, axis=1)
    arg = np.where(vals[:, 1] > vals[:, 0], idx[:, 1], idx[:, 0])
    return vals.max(axis=1), vals.min(axis=1), arg


def _waits(moves: np.ndarray, k: int) -> Iterator[tuple[int, int, int, int]]:
    """(k, e, s, r) of each wait [k, e) between two runs of moves, the run before [s, k) and after [e, r), from
    step ``k`` on, for a robot's (T,) ``moves``."""
    T = len(moves)
    while k < T:
        if moves[k] or not moves[k - 1]:
            k += 1
            continue
        e = k  # the waits [k, e) follow a move and ...
        while e < T and not moves[e]:
            e += 1
        if e == T:  # ... end the flight: nothing to merge
            return
        s, r = k, e
        while s > 0 and moves[s - 1]:  # the run before: [s, k)
            s -= 1
        while r < T and moves[r]:  # the run after: [e, r)
            r += 1
        yield k, e, s, r
        k = e + 1


def _retimings(col: np.ndarray, k: int, e: int, s: int, r: int) -> list[tuple[np.ndarray, int, int]]:
    """The robot's (T + 1, d) column with the wait [k, e) merged, each with the steps it changes: the run before
    [s, k) delayed, then the run after [e, r) advanced."""
    w = e - k
    late = col.copy()
    late[s:s + w + 1] = col[s]
    late[s + w:e + 1] = col[s:k + 1]
    soon = col.copy()
    soon[k:k + (r - e) + 1] = col[e:r + 1]
    soon[k + (r - e):r + 1] = col[r]
    return [(late, s, e), (soon, k, r)]


def _first_blocks_clear(paths: np.ndarray, robot: int, tries: list[tuple[np.ndarray, int, int]], scale: np.ndarray,
                        largest_move: float, index: CellIndex) -> np.ndarray:
    """(len(tries),) :func:`robot_clear`'s test of the first block of each (own, first, last) in ``tries``
    (last > first), at once: False where robot_clear fails there, True where the rest of the span decides.

    The same pairs and the same arithmetic as robot_clear's, element for element, so the same answers.
    """
    if not tries:
        return np.zeros(0, dtype=bool)
    first = np.array([f0 for _, f0, _ in tries])
    n = np.array([min(BLOCK, f1 - f0) for _, f0, f1 in tries])  # the first block's steps
    owner = np.repeat(np.arange(len(tries)), n)
    t = first[owner] + np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n)
    cols = np.stack([col for col, _, _ in tries])
    here, there = cols[owner, t] * scale, cols[owner, t + 1] * scale
    mine_step = _largest(np.abs(there - here))
    within = np.add.reduceat(mine_step, np.cumsum(n) - n) + largest_move * float(scale.max()) * n
    reach = MIN_SEPARATION + largest_move * float(scale.max()) + mine_step + _TOL
    q, j = index.near(t, here, reach, scale)
    keep = j != robot
    q, j = q[keep], j[keep]
    p0, p1 = paths[t[q], j] * scale, paths[t[q] + 1, j] * scale
    d0 = here[q] - p0
    close = _largest(np.abs(d0)) < MIN_SEPARATION + _largest(np.abs(p1 - p0)) + mine_step[q] + _TOL
    at = np.flatnonzero(close)
    c = owner[q[at]]
    gap = _largest(np.abs(paths[first[c], j[at]] * scale - cols[c, first[c]] * scale))
    close[at] = gap <= (MIN_SEPARATION + within + _TOL)[c]
    v = (there - here)[q[close]] - (p1[close] - p0[close])
    bad = np.zeros(len(tries), dtype=bool)
    bad[owner[q[close]][min_distance_during_move(d0[close], v) < MIN_SEPARATION - _TOL]] = True
    return ~bad


def merge_waits(paths: np.ndarray, downwash: float = 1.0,
                flight: FlightTime | None = None) -> tuple[np.ndarray, int]:
    """The (T + 1, N, d) ``paths`` with every wait between two runs of moves merged where safe, and the merges.

    See the module docstring. The result has the same steps, starts and ends, and each
    robot visits the same cells in the same order. With ``flight`` a merge is kept only if
    it does not lengthen the flight by that model.

    The plan's robots are kept in a :class:`CellIndex` as they merge, the first blocks of
    all of a robot's tries are tested at once, and each step's largest need is ranked again
    only where a merge changes it; the answers are those of testing every pair. On a
    1000-robot crossing's two calls this took 3.2 and 3.5 s instead of 12 and 18 s.
    """
    P = np.array(paths, dtype=np.int64)
    T, N = len(P) - 1, P.shape[1]
    if T < 3:
        return P, 0
    scale = downwash_scale(P.shape[-1], downwash)
    # a merge re-times a robot's own moves, so the largest move of the plan stays what it is
    largest_move = float(np.abs(np.diff(P, axis=0)).max())
    steps = None if flight is None else _Steps(*flight.needs(P))
    index = CellIndex(P)
    total = np.inf if steps is None or flight is None else flight.duration(steps.needs.max(axis=1),
                                                                            steps.lengths.max(axis=1))
    merged = 0
    for _ in range(PASSES):
        before = merged
        for i in range(N):
            k = 1
            moves = np.any(P[1:, i] != P[:-1, i], axis=1)  # again after each merge of this robot
            while True:
                waits = list(_waits(moves, k))
                tries = [c for w in waits for c in _retimings(P[:, i], *w)]  # each wait's late, then soon
                # most tries fail in their first block: those of every wait are tested at once, and they hold
                # until this robot's column changes
                first = _first_blocks_clear(P, i, tries, scale, largest_move, index)
                k = 0
                for n, (col, f0, f1) in enumerate(tries):
                    if not first[n] or not robot_clear(P, i, f0, f1, scale, col, largest_move, index):
                        continue
                    if steps is not None and flight is not None:
                        need_i, len_i = flight.needs(col[:, None])
                        need, longest = steps.without(i)
                        t = flight.duration(np.maximum(need, need_i[:, 0]), np.maximum(longest, len_i[:, 0]))
                        if t > total + 1e-9:
                            continue
                        steps.set(i, need_i[:, 0], len_i[:, 0])
                        total = t
                    index.move(i, P[:, i], col)
                    P[:, i] = col
                    moves = np.any(P[1:, i] != P[:-1, i], axis=1)
                    merged += 1
                    k = waits[n // 2][1] + 1  # on after the merged wait, with the new column
                    break
                if not k:
                    break
        if merged == before:
            break
    return P, merged
