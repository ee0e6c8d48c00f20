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

from mrfswarm.discrete.merge_waits import robot_clear
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
    """
    P = np.array(paths, dtype=np.int64)
    T, N = len(P) - 1, P.shape[1]
    if T < 2:
        return P, 0
    scale = downwash_scale(P.shape[-1], downwash)
    # a dropped loop only removes moves, so the plan's largest move bounds every move after it
    largest_move = float(np.abs(np.diff(P, axis=0)).max())
    dropped = 0
    while True:
        before = dropped
        for i in range(N):
            later = returns(P[:, i])
            s = 0
            while s < T - 1:
                for u in later[s]:  # the longest loop first
                    col = P[:, i].copy()
                    col[s + 1:u] = P[s, i]
                    if robot_clear(P, i, s, u, scale, col, largest_move):
                        P[:, i] = col
                        dropped += 1
                        s = u - 1
                        break
                s += 1
        if dropped == before:
            return P, dropped
