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
Stops after a sweep that moves no node, after ``Options.max_iter`` sweeps, or at
``Options.time_limit`` (checked between sweeps).
"""

from __future__ import annotations

import time

import numpy as np

from solvers.mrf.local_energy import LocalEnergy, colour_sweep
from solvers.mrf.problem import PairwiseMRF
from solvers.mrf.result import MRFResult, Options
from solvers.registry import Backend


def update_class(le: LocalEnergy, x: np.ndarray, tol: float) -> int:
    """Move every node of one independent class to its best feasible label, in place.

    Returns the number of nodes that moved.
    """
    c = le.feasible_costs(x)
    rows = np.arange(le.nodes.size)
    cur = x[le.nodes]
    best = np.argmin(c, axis=1)
    move = c[rows, best] < c[rows, cur] - tol
    if tol == 0:
        move &= best != cur
    x[le.nodes[move]] = best[move]
    return int(np.count_nonzero(move))


def descend(mrf: PairwiseMRF, x: np.ndarray, sweep: list[LocalEnergy], max_sweeps: int, tol: float,
            deadline: float | None = None) -> tuple[np.ndarray, list[float], list[int]]:
    """Run ICM sweeps from the feasible labelling ``x`` (copied) until a sweep moves nothing.

    Returns
    -------
    x
        The final labelling.
    trace
        Energy after each sweep.
    moves
        Nodes moved in each sweep.
    """
    x = np.array(x, dtype=np.intp, copy=True)
    trace: list[float] = []
    moves: list[int] = []
    for _ in range(max_sweeps):
        n = sum(update_class(le, x, tol) for le in sweep)
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
    capabilities=frozenset({"monotone"}),
)
