"""Dropping a robot's loops: where it comes back to a cell, it waits there instead (``mrf.drop_loops``).

Each MRF step picks every robot's next cell from its neighbourhood, and a robot that
makes way for a neighbour, or shuffles at the goal while the swarm packs around it,
often comes back to a cell it stood on a few steps before: A -> B -> A, or a longer
round A -> B -> C -> A. Flown, an A -> B -> A turns the robot back on itself (a full stop
at the reversal) and a longer round is a detour, and the step where one robot turns back
is slow for the whole swarm.
On seven random 64 x 64 clutter maps of 40 robots (the flight-quality bench's clutter40
and six more seeds), the plans of 64 to 71 steps held 3 to 17 such loops, 6 to 105 robot
steps spent in them.

After the MRF has chosen the paths, :func:`drop_loops` replaces each loop of a robot
(steps s < u with the same cell and a move between them) by a wait at that cell, where
the robot then stays at least one cell (in the downwash-scaled metric) from every other
robot during steps s..u: the invariant of :mod:`mrfswarm.discrete.safety`, checked by
:func:`~mrfswarm.discrete.merge_waits.robot_clear` (and on the whole plan afterwards).
The robot's cells are a subsequence of its old ones and its start and end are kept, so
its clearance from obstacles and the plan's length are unchanged; a loop is dropped
whole or not at all, the longest first (the latest return to the cell). Where the
neighbour it made way for needs the cell, the check fails and the loop stays. The waits
it leaves are then merged with the robot's other waits (:mod:`~mrfswarm.discrete.merge_waits`)
like any other. Measured (flight_quality bench, one run each, against the same code without it): stops per
robot clutter40 0.12 -> 0.07, the 300-robot crossing 0.30 -> 0.10, 200 robots in clutter 1.34 -> 1.21, the
seven clutter maps 0.18 -> 0.15 on average; makespans 0.1 to 0.7 % longer on forest, open field, clutter,
aisles and the big swarms, the same elsewhere.

This is a post-process of the paper's method (its robots keep the MRF's paths);
``mrf.drop_loops = false`` turns it off, as the paper's scenario configs do.
"""

from __future__ import annotations

from bisect import bisect_right

import numpy as np

from mrfswarm.discrete.merge_waits import CellIndex, robot_clear, waits_clear
from mrfswarm.geometry import downwash_scale


def returns(column: np.ndarray) -> list[list[int]]:
    """For each step s of one robot's path (T + 1, d): the later steps u at which it is back in its cell of s after
    leaving it (each (s, u) a loop), latest first."""
    cells = list(map(tuple, column))
    T = len(cells) - 1
    visits: dict[tuple, list[int]] = {}
    for t, cell in enumerate(cells):
        visits.setdefault(cell, []).append(t)
    leaves = [T + 1] * (T + 1)  # the first step after s in another cell
    for t in range(T - 1, -1, -1):
        leaves[t] = t + 1 if cells[t + 1] != cells[t] else leaves[t + 1]
    # each cell's visits are ascending: the returns after s are those past its first bisection point (a robot that
    # stands in one cell for long had every step scan all its visits: 2.4 M comparisons for 1000 robots)
    return [visits[cell][bisect_right(visits[cell], leaves[s]):][::-1] for s, cell in enumerate(cells)]


def drop_loops(paths: np.ndarray, downwash: float = 1.0) -> tuple[np.ndarray, int]:
    """The (T + 1, N, d) ``paths`` with every loop a robot can wait through safely dropped, and the loops dropped.

    See the module docstring. From each step of a robot's path, in order, its loops are
    tried longest first; a dropped loop's steps are skipped (a loop inside it is gone with
    it); where none of a step's loops can be dropped, the loops inside them are tried from
    the next steps. A dropped loop frees cells, so the sweep over robots repeats until it
    drops nothing.

    A dropped loop s..u is a wait at one cell, safe where each of its steps is
    (:func:`~mrfswarm.discrete.merge_waits.waits_clear`), and while a robot's loops are tried
    the other robots keep their paths: so each step's test is made once per robot and sweep,
    for all its loops at once, against the robots near (a
    :class:`~mrfswarm.discrete.merge_waits.CellIndex` of the plan), and only the loops these
    tests pass are checked by :func:`~mrfswarm.discrete.merge_waits.robot_clear` (which then
    drops them: the same loops as checking each). A robot's returns are found again only when
    its path changes, and the robots without loops are passed over. A 1000-robot crossing's two
    calls took 2.5 and 6.3 s when each loop was checked alone (the second: 15 278 checks, 97 %
    refused), 0.26 and 0.52 s so (408 robots' steps tested at once, 396 checks, all passed).
    """
    P = np.array(paths, dtype=np.int64)
    T = len(P) - 1
    if T < 2:
        return P, 0
    scale = downwash_scale(P.shape[-1], downwash)
    # a dropped loop only removes moves, so the plan's largest move bounds every move after it
    largest_move = float(np.abs(np.diff(P, axis=0)).max())
    index = CellIndex(P)  # a dropped loop's cells are the robot's own: within the plan's x and y
    # the robots with loops (a robot's returns change only with its own path, and a robot without loops keeps it)
    later = {i: returns(P[:, i]) for i in np.flatnonzero(_with_loops(P)).tolist()}
    dropped = 0
    while True:
        before = dropped
        for i in later:
            safe = _safe_until(P, i, later[i], scale, largest_move, index)
            s, changed = 0, False
            while s < T - 1:
                for u in later[i][s]:  # the longest loop first
                    if u > safe[s]:
                        continue
                    col = P[:, i].copy()
                    col[s + 1:u] = P[s, i]
                    if robot_clear(P, i, s, u, scale, col, largest_move, index):
                        index.move(i, P[:, i], col)
                        P[:, i] = col
                        dropped += 1
                        s, changed = u - 1, True
                        break
                s += 1
            if changed:
                later[i] = returns(P[:, i])
        if dropped == before:
            return P, dropped


def _with_loops(P: np.ndarray) -> np.ndarray:
    """(N,) whether each robot of the (T + 1, N, d) plan comes back to a cell it left: its runs of steps in one cell
    outnumber its cells."""
    c = P - P.min(axis=(0, 1))
    code = np.ravel_multi_index(tuple(np.moveaxis(c, -1, 0)), tuple((c.max(axis=(0, 1)) + 1).tolist()))  # (T + 1, N)
    runs = np.count_nonzero(np.diff(code, axis=0), axis=0)
    return runs > np.count_nonzero(np.diff(np.sort(code, axis=0), axis=0), axis=0)


def _safe_until(P: np.ndarray, robot: int, later: list[list[int]], scale: np.ndarray, largest_move: float,
                index: CellIndex) -> np.ndarray:
    """(T,) for each step s with loops (``later``, :func:`returns`): the first step u > s at which the robot could
    not have waited at its cell of s since s (its cells at the others' steps s..u - 1 tested at once, each
    (step, cell) once), or its latest return where none; 0 for the other steps."""
    T = len(P) - 1
    out = np.zeros(T, dtype=np.int64)
    starts = np.array([s for s in range(T) if later[s]], dtype=np.int64)
    if not len(starts):
        return out
    ends = np.array([later[s][0] for s in starts.tolist()], dtype=np.int64)  # each start's latest return
    n = ends - starts
    owner = np.repeat(np.arange(len(starts)), n)
    steps = starts[owner] + np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n)
    cells = P[starts[owner], robot]
    # a robot waits at few cells: each (step, cell) once
    low = cells.min(axis=0)
    size = cells.max(axis=0) - low + 1
    key = steps * int(np.prod(size)) + np.ravel_multi_index(tuple((cells - low).T), tuple(size.tolist()))
    _, first, back = np.unique(key, return_index=True, return_inverse=True)
    ok = waits_clear(P, robot, cells[first], steps[first], scale, largest_move, index)[back.ravel()]
    # the first failed step of each start's run of steps, or its end
    fail = np.where(ok, ends[owner], steps)
    out[starts] = np.minimum.reduceat(fail, np.cumsum(n) - n)
    return out
