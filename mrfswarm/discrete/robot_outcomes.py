"""Where each robot ended and why: the goal region, separation, and per-robot stop reasons.

A swarm of N robots cannot all sit on the goal cell. The goal region is the set of free
cells whose free-path distance to the goal is at most ``goal_radius + r_N``, where r_N is
the free-path distance within which the map holds :data:`GOAL_CELLS_PER_ROBOT` N free
cells: in open space a disc of radius 2 sqrt(N / pi) cells (a swarm at rest around its goal
with the paper's parameters fills it at ~1 robot per 4-6 cells: measured 1.4 cells for 5
robots, 7.1 for 50, 8.5 for 100), stretched along corridors where walls narrow it. Both
terms count cells, as the potentials do (``goal_radius`` unset is 3 cells), so the region
scales with the map's resolution: at 0.25 m cells, 8 robots get 0.75 m + 0.8 m.

Each robot gets a ``stop_reason`` when it ends outside the goal region:

``unreachable``
    No free path joins its cell to the goal (possible only with the Euclidean goal
    field; the geodesic one rejects such a scenario before planning).
``trapped``
    The static field itself holds it: steepest descent of rho_S from its cell ends in a
    local minimum outside the goal region (the Euclidean field in front of a concave
    wall; the robots queued behind the one in the minimum are trapped too).
``stalled``
    The static field would lead it into the goal region, but the run ended (converged,
    stalled or trapped) with the robot held where it is by the robots around it (the
    interaction, or cells it may not take).
``max_steps``
    The run ran out of steps while the robot could still descend.

A robot is *separated* when its nearest neighbour is farther than 1.5 d_min (d_min the
distance of the Morse potential's minimum, 8.42 cells with the paper's parameters): half
again the spacing the interaction favours. The interaction cannot pull such a robot
back by itself (with the paper's parameters its attraction never exceeds 0.012 per cell
per neighbour, against at least a_G / k_G = 0.15 per cell for the goal field); with a
goal, the goal field brings it to the goal region where the swarm gathers, and the
result reports every robot that still ends separated.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mrfswarm.discrete.motion import cell_values, clip_cells, moves_clear, stencil
from mrfswarm.discrete.planner import nearest_neighbour_cells

#: Free cells per robot in the goal region (besides scenario.goal_radius).
GOAL_CELLS_PER_ROBOT = 4

#: Run stop reasons that end the MRF steps with robots that could still descend.
_OUT_OF_STEPS = "max_steps"


def goal_region_radius(goal_path: np.ndarray, n_robots: int, goal_radius: float) -> float:
    """``goal_radius`` plus the free-path distance (metres) of the 4N-th nearest free cell to the goal.

    Parameters
    ----------
    goal_path
        (W, H) shortest free-path distance (metres) to the goal, ``inf`` where none.
    n_robots
        N.
    goal_radius
        ``scenario.goal_radius`` (metres).
    """
    finite = np.sort(goal_path[np.isfinite(goal_path)], axis=None)
    m = min(len(finite), GOAL_CELLS_PER_ROBOT * n_robots)
    return float(goal_radius + finite[m - 1])


@dataclass(frozen=True)
class RobotOutcome:
    """Where one robot ended and, if it is not at the goal, why.

    Attributes
    ----------
    robot
        Index.
    final_cell
        (2,) its last cell.
    goal_distance
        Free-path distance (metres) to the goal at the end; None without a goal or path.
    nearest_neighbour
        Distance (metres) to the nearest other robot at the end.
    at_goal
        In the goal region (None without a goal).
    separated
        Nearest neighbour farther than 1.5 d_min at the end.
    stop_reason
        None at the goal (or without one); else ``unreachable``, ``trapped``,
        ``stalled`` or ``max_steps`` (module docstring).
    """

    robot: int
    final_cell: np.ndarray
    goal_distance: float | None
    nearest_neighbour: float
    at_goal: bool | None
    separated: bool
    stop_reason: str | None


def descent_ends(free: np.ndarray, static: np.ndarray, order: int) -> np.ndarray:
    """(W, H, 2) or (W, H, D, 3): the cell where steepest descent of ``static`` from each cell stops.

    From each free cell, the clear move of the order-n stencil to the lowest cell (if it
    is lower), repeated until no move lowers ``static``: a local minimum of the static
    field. Other robots are ignored: this asks where the field itself leads. Vectorized
    by pointer doubling (log2(number of cells) rounds over all cells); occupied cells map
    to themselves.
    """
    shape = free.shape
    off = stencil(order, free.ndim)
    S = len(off)
    cells = np.argwhere(free)
    ok = moves_clear(free, cells, np.broadcast_to(np.arange(S), (len(cells), S)), order)
    to = clip_cells(cells[:, None, :] + off[None], shape)
    value = np.where(ok, cell_values(static, to), np.inf)
    value[:, 0] = cell_values(static, cells)  # stay: the move must lower rho_S strictly
    best = np.argmin(value, axis=1)  # ties keep the earlier index, "stay" first
    nxt = np.arange(free.size)
    here = np.ravel_multi_index(tuple(cells.T), shape)
    nxt[here] = np.ravel_multi_index(tuple(to[np.arange(len(cells)), best].T), shape)
    for _ in range(int(np.ceil(np.log2(max(2, free.size)))) + 1):
        nxt = nxt[nxt]
    return np.stack(np.unravel_index(nxt, shape), axis=-1).reshape(*shape, free.ndim)


def robot_outcomes(final: np.ndarray, free: np.ndarray, static: np.ndarray, order: int, resolution: float,
                   separation: float, run_stop_reason: str, goal_path: np.ndarray | None = None,
                   region_radius: float | None = None) -> list[RobotOutcome]:
    """One :class:`RobotOutcome` per robot.

    Parameters
    ----------
    final
        (N, d) final cells.
    free, static
        The free cells and rho_S over the grid ((W, H) or (W, H, D)).
    order
        Label-set order n (which moves a robot has).
    resolution
        Metres per cell.
    separation
        Nearest-neighbour distance (metres) beyond which a robot is separated.
    run_stop_reason
        How the discrete stage stopped (``DiscretePlan.stop_reason``).
    goal_path, region_radius
        Free-path distances (metres) to the goal and the goal region's radius; None
        without a goal.
    """
    final = np.asarray(final, dtype=np.intp)
    nn = nearest_neighbour_cells(final) * resolution
    if goal_path is not None:
        d = cell_values(goal_path, final)
        end = cell_values(descent_ends(free, static, order), final)
        field_leads_home = cell_values(goal_path, end) <= region_radius
    out = []
    for i, cell in enumerate(final):
        reason = None
        at_goal = dist = None
        if goal_path is not None:
            assert region_radius is not None  # given with goal_path
            dist = float(d[i]) if np.isfinite(d[i]) else None
            at_goal = bool(dist is not None and dist <= region_radius)
            if dist is None:
                reason = "unreachable"
            elif not at_goal:
                if not field_leads_home[i]:
                    reason = "trapped"
                else:
                    reason = _OUT_OF_STEPS if run_stop_reason == _OUT_OF_STEPS else "stalled"
        out.append(RobotOutcome(robot=i, final_cell=cell, goal_distance=dist, nearest_neighbour=float(nn[i]),
                                at_goal=at_goal, separated=bool(nn[i] > separation), stop_reason=reason))
    return out
