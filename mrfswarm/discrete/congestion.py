"""A goal field that routes the swarm around its own jams (``goal_potential.congestion``).

The geodesic goal field (:mod:`mrfswarm.discrete.goal_distance`) sends every robot along
the same shortest path. A swarm that meets a narrow gap on that path queues in front of
it for as many steps as it has robots, while gaps a few cells longer stand empty: 200
robots on a 128 x 128 map with 15 % obstacles had 164 at the goal after 300 steps, the
tail queueing behind one gap (``experiments/bench/flight_quality.py``, case big200).

Traffic engineers and crowd simulators (Treuille, Cooper & Popovic, "Continuum crowds",
SIGGRAPH 2006) price such congestion into the distance itself. Here, every ``every``
steps, the distance the goal potential uses is searched again with each move p -> q
costing

    |q - p| (1 + w rho(q)) + (k_G / a_G) max(0, rho_O(q) - rho_O(p)),

with rho the density of *stalled* robots: the cells of robots that did not move in the
last step and are outside the goal region, blurred by a Gaussian of :data:`SIGMA` cells
(so rho is the share of nearby cells holding a stalled robot, between 0 and 1), and w =
``goal_potential.congestion``. Robots on their way, and robots that have arrived, do not
count: in the open (the swarm flowing as one body) and in the goal region (which the
swarm is meant to fill) the field stays the static one. Behind a jam the cells of the
jam cost up to 1 + w times their length, so the robots behind take the next gap when it
is less than that much longer.

Measured (flight_quality bench, w = 5, every 5 steps, with merged waits, against the
static field): the 200 robots all arrive (225 steps), clutter40 flies 2.45 x the bound
instead of 2.98, the 300-robot crossing 1.31 instead of 1.40. Counting moving robots too
(a quarter each, w = 3) helped clutter more (2.2) but spread the crossing swarm sideways
(1.59), so they do not count.

w = 8 by default since the twenty-fourth session, measured on queues at gaps (flight_quality
bench, ``--cases`` funnel20, halls50, clutter40@1-7, big200, cross300, the 3-D maps): 50 robots
between two halls through three 2-cell corridors 1.69 -> 1.50 x the bound (0.64 -> 0.48 stops
per robot; 1.63 -> 1.52 on average over three more start seeds), 200 robots in clutter 1.81 ->
1.77 x, the seven clutter40 maps the same mean (1.343 x; their worst 1.44 -> 1.39, stops 0.05 ->
0.07 per robot), a funnel into one gap the same (there is no other gap), the rest the same
flights. Every 2 or 3 steps instead of 5 and w = 10 or 15 did no better on average.

The guarantee of the static field holds for every field searched here: each move still
costs at least its length plus the climb (1 + w rho >= 1), so the proof of
:mod:`mrfswarm.discrete.goal_distance` goes through word for word and rho_S has no local
minimum but the goal. What changes over time is which path is the shortest.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from mrfswarm.config import GoalPotentialConfig
from mrfswarm.discrete.goal_distance import GoalGraph
from mrfswarm.discrete.motion import cell_values
from mrfswarm.discrete.potentials import MAX_EXPONENT, goal_field

log = logging.getLogger(__name__)

#: Cells: the Gaussian that spreads a stalled robot over its neighbourhood. 1.5 makes a 3-cell-wide jam
#: nearly as costly as a solid one (rho ~ 0.6); measured on clutter40 and big200, 1.0 and 2.5 did no better.
SIGMA = 1.5


@dataclass(frozen=True)
class CongestionField:
    """Recomputes the goal field with the stalled robots' congestion priced in.

    Attributes
    ----------
    graph
        The search graph of the geodesic distance (moves, lengths, climbs).
    obstacle
        rho_O over the grid.
    goal_cfg
        a_G, k_G (the goal potential's parameters).
    resolution
        Metres per cell.
    weight
        w >= 0: a move into a cell full of stalled robots costs 1 + w times its length.
    every
        Steps between two searches.
    goal_path, region_radius
        The free-path distance to the goal and the goal region's radius (robots inside
        do not count).
    """

    graph: GoalGraph
    obstacle: np.ndarray
    goal_cfg: GoalPotentialConfig
    resolution: float
    weight: float
    every: int
    goal_path: np.ndarray
    region_radius: float

    def stalled(self, before: np.ndarray, after: np.ndarray) -> np.ndarray:
        """(N,) robots that stayed in their cell from ``before`` to ``after`` (N, d), outside the goal region."""
        stayed = np.all(np.asarray(before) == np.asarray(after), axis=1)
        return stayed & ~(cell_values(self.goal_path, after) <= self.region_radius)

    def density(self, cells: np.ndarray) -> np.ndarray:
        """rho over the grid: the cells (n, d) blurred by :data:`SIGMA`, between 0 and 1."""
        occ = np.zeros(self.graph.shape)
        if len(cells):
            occ[tuple(np.asarray(cells).T)] = 1.0
        return ndimage.gaussian_filter(occ, SIGMA, mode="constant")

    def fields(self, cells: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """(static field rho_S, goal distance) with the stalled robots at ``cells`` (n, d); None when the
        congested distance is so long that exp(d / k_G) would overflow (the caller keeps its field)."""
        factor = 1.0 + self.weight * cell_values(self.density(cells), self.graph.into)
        field = self.graph.search(self.graph.length * factor + self.graph.climb)[0]
        far = float(field[np.isfinite(field)].max(initial=0.0)) / self.resolution
        if far / self.goal_cfg.k > MAX_EXPONENT:
            log.warning("congested goal distance of %.0f cells overflows exp(d / k_G): the field stays", far)
            return None
        goal = np.array(np.unravel_index(self.graph.goal, self.graph.shape))
        static = goal_field(self.graph.shape, goal, self.resolution, self.goal_cfg, field) + self.obstacle
        return static, field
