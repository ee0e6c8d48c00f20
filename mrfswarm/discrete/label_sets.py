"""Label sets X_i^t: the cells each robot may move to in one MRF step.

X_i^t = cells with |x_i - x|^2 <= n (the n-th order neighbourhood; in 3-D squared distance
over three axes, so n = 3 is the 26-neighbourhood), with the
paper's heuristics: (a) cells occupied by obstacles or by other robots removed, (b) a cell
wanted by several robots given to one only (X_i ∩ X_j = ∅); optionally (c) the half
pointing away from the goal trimmed.

We add one rule the paper leaves implicit: the straight move must keep half a cell from
every occupied cell (:mod:`mrfswarm.discrete.motion`), so no move cuts a wall's corner or jumps a
wall. Label 0 is always "stay", which is always in X_i. Cells are (N, d), d = 2 or 3, by the
same lines. Rule (a) reads "the cells closer than one cell to another robot" in the
downwash-scaled metric (:func:`mrfswarm.geometry.downwash_scale`): in the plane (or with
c = 1) that is the robot's own cell, as in the paper; in 3-D with c > 1 also the voxels
within c - 1 above and below it (its downwash shadow), where no robot may end the step
while that robot stays. With ``follow`` both are kept, and the step's hard conflicts
(:mod:`mrfswarm.discrete.step_mrf`) decide, as they do for every move. Rule (b) too:
besides X_i ∩ X_j = ∅, no move of X_i ends within the shadow of a move of X_j (two robots
taking them would end closer than one cell); of two such moves the one first in the
contested rule's order stays (:func:`_shadowed`). In the plane nothing changes. Without it
a 3-D swarm with c = 2 has ~2 conflict pairs per robot in every step (targets stacked
one voxel apart), with it a few per hundred robots.

The paper gives a contested cell to one robot. With ``contested = "downhill"`` or
``"nearest"`` it goes to the robot nearest to it (so each robot's cells lie in
its own Voronoi cell, and moves of different robots rarely conflict), and among equally
near robots ``contested`` says who gets it (the paper does not). With ``"shared"`` rule (b)
is off: every robot keeps every candidate cell, and the step MRF decides who takes a cell
that several want, by their energy, through the hard conflicts it has for every pair of
moves that would come within a cell (:mod:`mrfswarm.discrete.step_mrf`; two robots never
end in one cell). The cell diagonally ahead of a robot is often nearer to the robot beside
it, for which it is a move sideways: given to that robot, it stays empty while the robot
that needed it waits or goes round. Measured (flight-quality bench, against "downhill";
2026-11-28, seventh session): 40 robots in 10 % clutter 67 -> 61 MRF steps, makespan over
its bound 1.44 -> 1.29 (refined 1.28 -> 1.21), six of seven such maps 3.7-10.8 % sooner
(one 3.9 % later), 30 robots in aisles 1.43 -> 1.33, 50 across an open field 1.12 -> 1.08,
200 in 15 % clutter 1.95 -> 1.83 with 1.25 -> 0.95 stops per robot; but a straight
crossing funnels: robots off the goal's row find the diagonal move toward it lower (the
8-connected distance) and take their neighbours' lanes, so 300 robots crossing an open
field 1.17 -> 1.29 with more waits, and of 1000 robots crossing 240 m only 985 at the goal
after 300 steps; the doorway 1.32 -> 1.36, field3d 15.94 -> 16.51 s. Hence neither is the default:
``contested = "auto"`` (the config's default) plans with both and keeps the plan that flies sooner
(:func:`mrfswarm.discrete.planner.plan_discrete`); these label sets take one rule.

- ``"shared"``: no robot is given a contested cell; the MRF decides.
- ``"queue"``: the label sets of ``"shared"``; the planner has the step's optimizer visit the
  robots that have waited longest first (:func:`mrfswarm.discrete.planner.step_model`), so
  the MRF gives a cell two robots need to the one that waited.
- ``"nearest"``: the lower index. In a crowd this can hand a cell to a robot that has no
  use for it (it lies behind that robot) while the robot beside it, for which it is the
  way forward, loses it: a swarm queued in a 2-cell corridor or doorway can lock up for
  good, every robot's way forward held by one that stays (with the geodesic field, 29 of
  64 runs with 50 robots on generated maps ended with robots held short of the goal;
  none with ``"downhill"`` or ``"shared"``). The paper's scenario configs use it (their discrete outputs
  are the ones reproduced).
- ``"downhill"``: the robot whose static field the cell lowers most,
  rho_S(x_i) - rho_S(cell), then the lower index. Where rho_S is flat (free space
  without a goal) it is ``"nearest"``.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from mrfswarm.config import CONTESTED_RULES
from mrfswarm.discrete.motion import MIN_SEPARATION, cell_values, clip_cells, in_grid, moves_clear, scaled, stencil


@dataclass(frozen=True)
class LabelSets:
    """Per-robot candidate moves, valid labels first.

    Attributes
    ----------
    index
        (N, L) int index of each label's move in ``stencil(order)``; padding is 0 (stay).
    count
        (N,) number of valid labels per robot (label 0 = stay is always valid).
    starts
        (N, d) current cells.
    order
        The neighbourhood order n.
    """

    index: np.ndarray
    count: np.ndarray
    starts: np.ndarray
    order: int

    @property
    def ndim(self) -> int:
        """d, the grid's number of axes (2 or 3)."""
        return int(self.starts.shape[1])

    @cached_property
    def offsets(self) -> np.ndarray:
        """(N, L, d) int cell offset of each label; padding is (0, ..., 0)."""
        return _read_only(stencil(self.order, self.ndim)[self.index])

    @cached_property
    def cells(self) -> np.ndarray:
        """(N, L, d) the cell each label moves to."""
        return _read_only(self.starts[:, None, :] + self.offsets)

    @cached_property
    def valid(self) -> np.ndarray:
        """(N, L) True for real labels, False for padding."""
        return _read_only(np.arange(self.index.shape[1])[None, :] < self.count[:, None])


def _read_only(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a


def shadow_offsets(ndim: int, downwash: float = 1.0) -> np.ndarray:
    """(K, d) nonzero integer offsets closer than one cell in the downwash-scaled metric.

    None in the plane or with c = 1; in 3-D (0, 0, +-k) for 0 < k < c.
    """
    m = int(np.ceil(downwash)) if ndim == 3 else 0
    z = np.arange(-m, m + 1)
    off = np.zeros((len(z), ndim), dtype=np.intp)
    if ndim == 3:
        off[:, 2] = z
    close = (z != 0) & (np.linalg.norm(scaled(off, downwash), axis=1) < MIN_SEPARATION - 1e-9)
    return off[close]


def _shadowed(cell_id: np.ndarray, moving: np.ndarray, priority: np.ndarray, robot: np.ndarray,
              shadows: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    """(C,) bool: candidate moves in the downwash shadow of a better one of another robot.

    Rule (b) in the scaled metric: after each cell has one claimant, a move to a voxel
    within c - 1 above or below another robot's move target loses to it when that one
    comes first in ``priority`` (the contested rule's order, without the cell). Only
    ``moving`` candidates (kept, not "stay") take part; stays are never dropped.
    """
    C = len(cell_id)
    rank = np.empty(C, dtype=np.intp)
    rank[priority] = np.arange(C)
    who = np.full(int(np.prod(shape)), -1, dtype=np.intp)
    at = np.flatnonzero(moving)
    who[cell_id[at]] = at
    cells = np.stack(np.unravel_index(cell_id[at], shape), axis=1)
    lose = np.zeros(C, dtype=bool)
    for o in shadows:
        nb = cells + o
        inside = in_grid(nb, shape)
        rival = np.full(len(at), -1, dtype=np.intp)
        rival[inside] = who[np.ravel_multi_index(tuple(nb[inside].T), shape)]
        beaten = (rival >= 0) & (robot[np.maximum(rival, 0)] != robot[at]) & (rank[np.maximum(rival, 0)] < rank[at])
        lose[at[beaten]] = True
    return lose


def label_sets(free: np.ndarray, starts: np.ndarray, order: int, goal_cell: np.ndarray | None = None,
               trim_backward: bool | np.ndarray = False, static: np.ndarray | None = None,
               contested: str = "nearest", goal_distance: np.ndarray | None = None, follow: bool = False,
               downwash: float = 1.0, trim_slack: float = 0.0) -> LabelSets:
    """Build X_i^t for every robot.

    Parameters
    ----------
    free
        (W, H) or (W, H, D) bool grid, True where free.
    starts
        (N, d) current cells, distinct and free (d = ``free.ndim``).
    order
        n, the neighbourhood order.
    goal_cell
        Needed only with ``trim_backward``.
    trim_backward
        Drop moves pointing away from the goal; "stay" is kept. Away: a negative dot
        product with the direction to the goal (the paper's), or, when ``goal_distance``
        is given, a distance to the goal along free paths larger by more than ``trim_slack``
        (the straight direction would cut the way around a wall). A bool for every robot, or
        (N,) bool: the robots it applies to (the planner lifts it for robots stuck in their
        cell, ``mrf.trim_escape``).
    static
        The static field rho_S over the grid; needed by ``contested = "downhill"``.
    contested
        Who gets a contested cell: a name in :data:`CONTESTED_RULES`.
    goal_distance
        The goal field's distance to the goal (:mod:`mrfswarm.discrete.goal_distance`),
        for ``trim_backward``; None: trim by direction.
    follow
        Keep cells where another robot stands now as candidates (rule (a) off for them):
        such a cell is its occupant's "stay" and, besides, goes to one other robot (by the
        ``contested`` rule), which may enter it only when the occupant leaves in the same
        step in a direction that keeps them one cell apart: the step's hard conflicts
        (:mod:`mrfswarm.discrete.step_mrf`) forbid every other combination. A queue then
        moves in one step as a whole instead of one robot per step. Staying still is
        always feasible (everybody staying breaks no conflict), so every optimizer's
        starting point and :func:`solvers.mrf.problem.repair` are unchanged.
    downwash
        c >= 1: rule (a) also removes the cells within c - 1 voxels right above or below
        another robot (3-D; see the module docstring).
    trim_slack
        With ``goal_distance``: how much (its units) a kept move may raise it. The distance
        is measured over 8 (26) move directions, so a sideways move, square to the way to
        the goal, raises it by 0.41 to 0.59 cell (on voxels up to 0.68); half a cell keeps
        most of them, as the paper's dot-product rule keeps every square move
        (``mrf.trim_slack``).
    """
    # "auto" picks a rule per plan, "queue" is "shared" with another visiting order (both: plan_discrete)
    rules = [r for r in CONTESTED_RULES if r not in ("auto", "queue")]
    if contested not in rules:
        raise ValueError(f"contested = {contested!r}: label sets need one of {', '.join(rules)}")
    if contested == "downhill" and static is None:
        raise ValueError('contested = "downhill" needs the static field')
    starts = np.asarray(starts, dtype=np.intp)
    N = len(starts)
    off = stencil(order, free.ndim)
    S = len(off)
    cand = starts[:, None, :] + off[None, :, :]  # (N, S, d)
    ok = moves_clear(free, starts, np.broadcast_to(np.arange(S), (N, S)), order)
    # (a) cells closer than one cell (scaled) to another robot: the cell it stands on and, on
    # voxels with downwash, its shadow; each marked with the robot it is near (-2: several)
    clipped = clip_cells(cand, free.shape)
    if not follow:
        near = starts[:, None, :] + np.concatenate([np.zeros((1, free.ndim), np.intp),
                                                    shadow_offsets(free.ndim, downwash)])[None]  # (N, 1 + K, d)
        owner = np.broadcast_to(np.arange(N)[:, None], near.shape[:2])
        inside = in_grid(near, free.shape)
        flat = np.ravel_multi_index(tuple(near[inside].T), free.shape)
        robot_near = np.full(free.size, -1, dtype=np.intp)
        robot_near[flat] = owner[inside]
        if near.shape[1] > 1:  # shadows can overlap (robots c apart in z share the voxels between)
            srt = np.sort(flat)
            robot_near[srt[1:][srt[1:] == srt[:-1]]] = -2
        other = cell_values(robot_near.reshape(free.shape), clipped)
        ok &= (other == -1) | (other == np.arange(N)[:, None])
    # (c) the half that points away from the goal
    if np.any(trim_backward) and goal_cell is not None:
        keep_all = ~np.broadcast_to(np.asarray(trim_backward, dtype=bool), (len(starts),))[:, None]
        if goal_distance is None:
            to_goal = np.asarray(goal_cell)[None, :] - starts  # (N, d)
            ok &= ((off[None, :, :] * to_goal[:, None, :]).sum(-1) >= 0) | keep_all
        else:
            rise = cell_values(goal_distance, clipped) - cell_values(goal_distance, starts)[:, None]
            ok &= (rise <= trim_slack) | keep_all
    ok[:, 0] = True  # staying is always allowed (the cell is free and one's own)
    # (b) X_i ∩ X_j = ∅: a contested cell goes to one robot (the first in the sort below); with "shared" every
    # robot keeps it (the sort then only orders the 3-D shadow rule below)
    r, s = np.nonzero(ok)
    cell_id = np.ravel_multi_index(tuple(cand[r, s].T), free.shape)  # (in 2-D, x H + y)
    dist2 = (off[s] ** 2).sum(axis=1)
    keys: tuple[np.ndarray, ...] = (r, dist2)
    if contested == "downhill" or (contested == "shared" and static is not None):
        assert static is not None  # checked above
        rise = cell_values(static, cand[r, s]) - cell_values(static, starts[r])
        keys = (r, rise, dist2)
    order_idx = np.lexsort((*keys, cell_id))
    if contested == "shared":  # every robot keeps its candidates; the step's hard conflicts decide
        keep = np.ones(len(r), dtype=bool)
    elif follow:  # the occupant keeps its cell (its stay); the others compete for it as for any cell
        stay = s == 0
        order_idx = np.concatenate([order_idx[stay[order_idx]], order_idx[~stay[order_idx]]])
        rest = order_idx[len(order_idx) - int((~stay).sum()):]
        first_rest = np.ones(len(rest), dtype=bool)
        first_rest[1:] = cell_id[rest][1:] != cell_id[rest][:-1]
        keep = stay.copy()
        keep[rest[first_rest]] = True
    else:
        first = np.ones(len(order_idx), dtype=bool)
        first[1:] = cell_id[order_idx][1:] != cell_id[order_idx][:-1]
        keep = np.zeros(len(r), dtype=bool)
        keep[order_idx[first]] = True
    shadows = shadow_offsets(free.ndim, downwash)
    if len(shadows):
        keep &= ~_shadowed(cell_id, keep & (s != 0), np.lexsort(keys), r, shadows,
                           free.shape)
    ok[:] = False
    ok[r[keep], s[keep]] = True
    # compact: valid labels first, in stencil order (stay first)
    count = ok.sum(axis=1)
    L = int(count.max())
    pos = np.argsort(~ok, axis=1, kind="stable")[:, :L]
    valid = np.arange(L)[None, :] < count[:, None]
    index = np.where(valid, pos, 0)
    return LabelSets(index=index, count=count, starts=starts, order=order)
