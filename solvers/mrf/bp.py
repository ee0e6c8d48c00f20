"""Min-sum loopy belief propagation, damped, with a parallel (flooding) schedule.

Pearl, J. (1988). "Probabilistic Reasoning in Intelligent Systems", ch. 4 (max-product);
Weiss, Y. & Freeman, W. T. (2001). "On the optimality of solutions of the max-product
belief-propagation algorithm in arbitrary graphs". IEEE Trans. Inf. Theory 47(2).

On the pairwise model of :func:`~solvers.mrf.penalized.penalized_pairs` (edges plus the
conflict pairs, with forbidden label pairs costing the finite ``Options.conflict_penalty``)
every iteration recomputes all messages at once

.. math::

    m_{i \\to j}(b) = \\min_a \\Big[U_i(a) + \\sum_{k \\ne j} m_{k \\to i}(a) + W_{ij}(a, b)\\Big],

normalizes each to min 0, and damps: ``m = d * m_old + (1 - d) * m_new`` with
d = ``Options.damping``. Beliefs b_i = U_i + sum of incoming messages; the decoding is
x_i = argmin b_i. Conflicts are thus handled as large finite penalties while passing
messages (inf costs would give inf - inf), and a decoding that still breaks one is
repaired (counted in ``MRFResult.repaired`` and ``stats["repairs"]``).

Every iteration's decoding is offered to an :class:`~solvers.mrf.incumbent.Incumbent`
and the best feasible labelling seen (or ``initial``) is returned; ``energy_trace`` is
its energy after each iteration, ``stats["decoded_energy"]`` each decoding's (repaired)
energy. Stops when no message changes by more than ``Options.tol``, after
``Options.max_iter`` iterations, or at ``Options.time_limit``. On a tree (no conflicts,
unique optimum) the messages converge and the decoding is the exact optimum. With
``Options.polish`` the result is finished with ICM.
"""

from __future__ import annotations

import time

import numpy as np

from solvers.mrf.capabilities import MRFCapabilities
from solvers.mrf.incumbent import Incumbent
from solvers.mrf.penalized import auto_penalty, penalized_pairs
from solvers.mrf.problem import PairwiseMRF
from solvers.mrf.result import MRFResult, Options
from solvers.registry import Backend


def minimize(mrf: PairwiseMRF, options: Options) -> MRFResult:
    """Damped min-sum loopy BP; see the module docstring."""
    t_start = time.perf_counter()
    deadline = None if options.time_limit is None else t_start + options.time_limit
    N, L = mrf.n_nodes, mrf.max_labels
    penalty = auto_penalty(mrf) if options.conflict_penalty is None else options.conflict_penalty
    pairs, tables = penalized_pairs(mrf, penalty)
    P = len(pairs)
    # directed message d < P: pairs[d,0] -> pairs[d,1]; d >= P: the reverse direction
    src = np.concatenate([pairs[:, 0], pairs[:, 1]])
    dst = np.concatenate([pairs[:, 1], pairs[:, 0]])
    rev = np.concatenate([np.arange(P, 2 * P), np.arange(P)])
    scatter = (dst[:, None] * L + np.arange(L)).ravel()
    msg = np.zeros((2 * P, L))
    best = Incumbent(mrf)
    trace, decoded = [], []
    delta = np.inf
    it = 0
    for it in range(1, options.max_iter + 1):  # noqa: B007 (the count of iterations run, read after the loop)
        belief = mrf.unary + np.bincount(scatter, weights=msg.ravel(), minlength=N * L).reshape(N, L)
        h = belief[src] - msg[rev]  # inf on the sender's padding labels
        new = np.empty_like(msg)
        new[:P] = (h[:P, :, None] + tables).min(axis=1)
        new[P:] = (h[P:, None, :] + tables).min(axis=2)
        new -= new.min(axis=1, keepdims=True)
        if options.damping:
            new = options.damping * msg + (1.0 - options.damping) * new
        delta = float(np.abs(new - msg).max()) if msg.size else 0.0
        msg = new
        belief = mrf.unary + np.bincount(scatter, weights=msg.ravel(), minlength=N * L).reshape(N, L)
        decoded.append(best.offer(np.argmin(belief, axis=1)))
        trace.append(best.energy)
        if delta <= options.tol or (deadline is not None and time.perf_counter() >= deadline):
            break
    stats = {"penalty": penalty, "pairs": P, "max_message_change": delta, "converged": delta <= options.tol,
             "decoded_energy": decoded}
    return best.result("bp", options, trace, it, t_start, deadline, stats)


BACKEND = Backend(
    name="bp",
    entry=minimize,
    summary="damped min-sum loopy belief propagation, conflicts as finite penalties (Pearl 1988)",
    capabilities=MRFCapabilities(optimal=False, lower_bound=False, exact_on_trees=True, monotone=False, stochastic=False),
)
