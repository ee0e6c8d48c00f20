"""Annealed Gibbs sampling (simulated annealing with heat-bath moves).

Geman, S. & Geman, D. (1984). "Stochastic relaxation, Gibbs distributions, and the
Bayesian restoration of images". IEEE Trans. PAMI 6(6), 721–741.
Xi, W., Tan, X. & Baras, J. S. (2006). "Gibbs sampler-based coordination of autonomous
swarms". Automatica 42(7), 1107–1119 (and Baras & Tan's earlier swarm papers).

Sweep k draws every node's label from the conditional Gibbs distribution at temperature
T_k,

.. math::

    P(x_i = a \\mid x_{-i}) \\propto \\exp(-\\ell_i(a \\mid x) / T_k),

restricted to the labels that break no conflict with the others' current labels (so the
chain stays feasible: the current label is always allowed). Nodes of one colour class
of the union graph (edges + conflicts) are conditionally independent given the rest and
are drawn together, which is exactly a sequential (systematic-scan) sampler.

Schedules (``Options.schedule``): ``"geometric"``, T_k = T_0 c^k with c =
``Options.cooling`` (the practical choice); ``"log"``, T_k = T_0 / log(k + 2), Geman &
Geman's schedule, whose convergence guarantee needs T_0 of the order of N times the
largest local energy range and far more sweeps than are practical. T_0 is
``Options.temperature``, or, if ``None``, the median over nodes of the standard
deviation of \\ell_i over the feasible labels at ``initial``.

Runs ``Options.max_iter`` sweeps (or until ``Options.time_limit``), seeded by
``Options.seed``, and returns the best labelling seen after any sweep (or ``initial``);
``energy_trace`` is that best energy after each sweep, ``stats["chain_energy"]`` the
chain's own energy. With ``Options.polish`` the result is finished with ICM.
"""

from __future__ import annotations

import time

import numpy as np

from solvers.mrf.capabilities import MRFCapabilities
from solvers.mrf.incumbent import Incumbent
from solvers.mrf.local_energy import LocalEnergy, colour_sweep
from solvers.mrf.problem import PairwiseMRF
from solvers.mrf.result import MRFResult, Options
from solvers.registry import Backend


def initial_temperature(mrf: PairwiseMRF, sweep: list[LocalEnergy]) -> float:
    """Median over nodes of the std of the feasible local energies at ``initial`` (1 if that is 0)."""
    spreads = []
    for le in sweep:
        c = le.feasible_costs(mrf.initial)
        ok = np.isfinite(c)
        n = ok.sum(axis=1)
        z = np.where(ok, c, 0.0)
        mean = z.sum(axis=1) / n
        var = np.where(ok, (z - mean[:, None]) ** 2, 0.0).sum(axis=1) / n
        spreads.append(np.sqrt(var[n > 1]))
    s = np.concatenate(spreads)
    t = float(np.median(s)) if s.size else 0.0
    return t if t > 0 else 1.0


def temperature(options: Options, t0: float, k: int) -> float:
    """T_k of the schedule chosen in ``options``."""
    if options.schedule == "log":
        return t0 / np.log(k + 2.0)
    return t0 * options.cooling ** k


def sample_class(le: LocalEnergy, x: np.ndarray, T: float, rng: np.random.Generator) -> None:
    """Draw the labels of one independent class from their conditionals at temperature T, in place."""
    c = le.feasible_costs(x)
    z = c - c.min(axis=1, keepdims=True)  # the current label is feasible: min is finite
    with np.errstate(over="ignore"):  # z / T -> inf when cold: weight 0, as it should
        w = np.exp(-z / max(T, np.finfo(float).tiny))  # inf -> 0: forbidden and padding labels are never drawn
    cum = np.cumsum(w, axis=1)
    u = (1.0 - rng.random(le.nodes.size)) * cum[:, -1]  # in (0, total]: a zero-weight label is never hit
    x[le.nodes] = np.minimum((cum < u[:, None]).sum(axis=1), c.shape[1] - 1)


def minimize(mrf: PairwiseMRF, options: Options) -> MRFResult:
    """Annealed Gibbs sampling from ``mrf.initial``; see the module docstring."""
    t_start = time.perf_counter()
    deadline = None if options.time_limit is None else t_start + options.time_limit
    rng = np.random.default_rng(options.seed)
    sweep = colour_sweep(mrf)
    t0 = options.temperature if options.temperature is not None else initial_temperature(mrf, sweep)
    best = Incumbent(mrf)
    x = mrf.initial.copy()
    trace, chain = [], []
    for k in range(options.max_iter):
        T = temperature(options, t0, k)
        for le in sweep:
            sample_class(le, x, T, rng)
        chain.append(best.offer(x))
        trace.append(best.energy)
        if deadline is not None and time.perf_counter() >= deadline:
            break
    stats = {"t0": t0, "t_final": temperature(options, t0, len(trace) - 1), "chain_energy": chain,
             "colours": len(sweep)}
    return best.result("gibbs", options, trace, len(chain), t_start, deadline, stats, sweep=sweep)


BACKEND = Backend(
    name="gibbs",
    entry=minimize,
    summary="annealed Gibbs sampler (Geman & Geman 1984; Xi, Tan & Baras 2006), seeded",
    capabilities=MRFCapabilities(optimal=False, lower_bound=False, exact_on_trees=False, monotone=False, stochastic=True),
)
