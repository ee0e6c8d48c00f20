"""Iterated Conditional Modes (ICM), the paper's optimizer.

Besag, J. (1986). "On the statistical analysis of dirty pictures". Journal of the Royal
Statistical Society B 48(3), 259–302.

Starting from ``mrf.initial``, each node in turn takes the label that minimizes its local
energy

.. math::

    \\ell_i(a \\mid x) = U_i(a) + \\sum_{e \\ni i} W_e(a, x_{j(e)})

among the labels that break no conflict with the other nodes' current labels; a node
moves only if that lowers \\ell_i by more than ``Options.tol`` (ties keep the current
label), so E(x) decreases strictly with every move and the iteration terminates. The
current labelling stays feasible throughout, because a node's current label is always
allowed.

Sweeps visit the colour classes of a proper colouring of the union graph (edges and
conflicts, :func:`~solvers.mrf.local_energy.colour_classes`); a class is an independent
set, so updating it in one array expression is exactly sequential ICM in that order.
After the first sweep only nodes with a neighbour that moved since their last
evaluation are evaluated again (the others cannot move), which leaves the result
unchanged and makes the later sweeps cheap.
Stops after a sweep that moves no node, after ``Options.max_iter`` sweeps, or at
``Options.time_limit`` (checked between sweeps).
"""

from __future__ import annotations

import time

import numpy as np

from solvers.mrf.capabilities import MRFCapabilities
from solvers.mrf.local_energy import LocalEnergy, colour_sweep, neighbours, union_adjacency
from solvers.mrf.problem import PairwiseMRF
from solvers.mrf.result import MRFResult, Options
from solvers.registry import Backend


def update_class(le: LocalEnergy, x: np.ndarray, tol: float, dirty: np.ndarray | None = None) -> np.ndarray:
    """Move the nodes of one independent class to their best feasible labels, in place.

    With ``dirty`` (N,) only the class's dirty nodes are evaluated (and marked clean).
    Returns the nodes that moved.
    """
    sel = None
    nodes = le.nodes
    if dirty is not None:
        sel = dirty[nodes]
        if not sel.any():
            return nodes[:0]
        if sel.all():
            sel = None
        else:
            nodes = nodes[sel]
        dirty[nodes] = False
    c = le.feasible_costs(x, sel)
    rows = np.arange(nodes.size)
    cur = x[nodes]
    best = np.argmin(c, axis=1)
    move = c[rows, best] < c[rows, cur] - tol
    if tol == 0:
        move &= best != cur
    x[nodes[move]] = best[move]
    return nodes[move]


def descend(mrf: PairwiseMRF, x: np.ndarray, sweep: list[LocalEnergy], max_sweeps: int, tol: float,
            deadline: float | None = None,
            adjacency: tuple[np.ndarray, np.ndarray] | None = None,
            dirty: np.ndarray | None = None) -> tuple[np.ndarray, list[float], list[int]]:
    """Run ICM sweeps from the feasible labelling ``x`` (copied) until a sweep moves nothing.

    A node is evaluated only if it is ``dirty`` (initially all nodes, or the given (N,)
    mask when the caller knows the others are at their best) or a neighbour (edge or
    conflict) moved since its last evaluation; the others could not move, so the result
    is that of plain ICM in the same order.

    Returns
    -------
    x
        The final labelling.
    trace
        Energy after each sweep.
    moves
        Nodes moved in each sweep.
    """
    indptr, nbr = union_adjacency(mrf) if adjacency is None else adjacency
    x = np.array(x, dtype=np.intp, copy=True)
    dirty = np.ones(mrf.n_nodes, dtype=bool) if dirty is None else np.array(dirty, dtype=bool, copy=True)
    trace: list[float] = []
    moves: list[int] = []
    for _ in range(max_sweeps):
        n = 0
        for le in sweep:
            moved = update_class(le, x, tol, dirty)
            if moved.size:
                n += moved.size
                dirty[neighbours(indptr, nbr, moved)] = True
        moves.append(n)
        trace.append(mrf.energy(x))
        if n == 0 or (deadline is not None and time.perf_counter() >= deadline):
            break
    return x, trace, moves


def minimize(mrf: PairwiseMRF, options: Options) -> MRFResult:
    """ICM from ``mrf.initial``; see the module docstring."""
    t0 = time.perf_counter()
    deadline = None if options.time_limit is None else t0 + options.time_limit
    sweep = colour_sweep(mrf)
    t_setup = time.perf_counter() - t0
    x, trace, moves = descend(mrf, mrf.initial, sweep, options.max_iter, options.tol, deadline)
    return MRFResult(
        labels=x,
        energy=trace[-1],
        energy_trace=np.array(trace),
        iterations=len(trace),
        time_s=time.perf_counter() - t0,
        method="icm",
        stats={"moves": moves, "colours": len(sweep), "setup_s": t_setup,
               "initial_energy": mrf.energy(mrf.initial), "converged": moves[-1] == 0},
    )


BACKEND = Backend(
    name="icm",
    entry=minimize,
    summary="iterated conditional modes (Besag 1986), vectorized by colour classes; the paper's method",
    capabilities=MRFCapabilities(optimal=False, lower_bound=False, exact_on_trees=False, monotone=True, stochastic=False),
)
