"""Every registered MRF method against brute force, and each method's own guarantees.

Methods come from ``solvers.mrf.METHODS`` (never a hand-written list); what a method
promises is read from its capability flags.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from solvers import mrf
from solvers.errors import InvalidProblem
from solvers.mrf.exact import MAX_LABELLINGS
from solvers.mrf.gibbs import sample_class
from solvers.mrf.local_energy import colour_sweep
from solvers.mrf.penalized import auto_penalty, penalized_pairs
from solvers.mrf.synthetic import random_mrf, swarm_mrf
from solvers.registry import Backend, Registry

ALL = mrf.METHODS.names()
HEURISTIC = [b.name for b in mrf.METHODS if not b.capabilities.optimal]
WITH_BOUND = [b.name for b in mrf.METHODS if b.capabilities.lower_bound]
TREE_EXACT = [b.name for b in mrf.METHODS if b.capabilities.exact_on_trees]
MONOTONE = [b.name for b in mrf.METHODS if b.capabilities.monotone]


def test_registry_has_the_ablation_methods():
    assert {"icm", "gibbs", "bp", "trws", "lazy_flipper", "exact"} <= set(ALL)
    assert mrf.DEFAULT_METHOD == "icm" and ALL[0] == "icm"
    assert all(not b.requires for b in mrf.METHODS if b not in mrf.METHODS.added())  # a plugin's may need a package


def check_result(m: mrf.PairwiseMRF, res: mrf.MRFResult, method: str, max_iter: int = mrf.Options().max_iter) -> None:
    assert res.method == method
    assert m.is_feasible(res.labels)
    assert res.energy == pytest.approx(m.energy(res.labels), abs=1e-9)
    assert res.energy <= m.energy(m.initial) + 1e-9  # no method returns worse than staying put
    assert res.energy_trace.size >= 1 and res.energy_trace[-1] == pytest.approx(res.energy, abs=1e-9)
    assert 0 <= res.iterations <= max_iter  # the cap holds
    assert res.time_s > 0  # measured
    assert 0 <= res.repaired <= m.n_nodes


@pytest.mark.parametrize("method", ALL)
@given(seed=st.integers(0, 2**32 - 1), N=st.integers(1, 6), L=st.integers(1, 4))
@settings(max_examples=40, deadline=None)
def test_method_is_feasible_and_never_below_the_optimum(method, seed, N, L):
    m = random_mrf(np.random.default_rng(seed), N, L)
    opt = mrf.minimize(m, "exact").energy
    res = mrf.minimize(m, method)
    check_result(m, res, method)
    assert res.energy >= opt - 1e-9
    if method in WITH_BOUND:
        assert res.lower_bound is not None and res.lower_bound <= opt + 1e-9


@pytest.mark.parametrize("method", MONOTONE)
@given(seed=st.integers(0, 2**32 - 1), N=st.integers(1, 7), L=st.integers(1, 4))
@settings(max_examples=30, deadline=None)
def test_monotone_methods_never_raise_the_energy(method, seed, N, L):
    m = random_mrf(np.random.default_rng(seed), N, L)
    res = mrf.minimize(m, method)
    trace = np.concatenate([[m.energy(m.initial)], res.energy_trace])
    assert np.all(np.diff(trace) <= 1e-9)


def random_tree(rng: np.random.Generator, N: int) -> np.ndarray:
    return np.array([[rng.integers(0, i), i] for i in range(1, N)], dtype=int).reshape(-1, 2)


@pytest.mark.parametrize("method", TREE_EXACT)
@pytest.mark.parametrize("shape", ["chain", "tree"])
@pytest.mark.parametrize("seed", range(12))
def test_exact_on_chains_and_trees_without_conflicts(method, shape, seed):
    rng = np.random.default_rng(seed)
    N = int(rng.integers(2, 9))
    L = int(rng.integers(2, 5))
    edges = np.stack([np.arange(N - 1), np.arange(1, N)], 1) if shape == "chain" else random_tree(rng, N)
    m = random_mrf(rng, N, L, p_conf=0.0, edges=edges)
    opt = mrf.minimize(m, "exact").energy
    res = mrf.minimize(m, method, mrf.Options(max_iter=300))
    assert res.energy == pytest.approx(opt, abs=1e-9)
    if method in WITH_BOUND:
        assert res.lower_bound == pytest.approx(opt, abs=1e-7)


@given(seed=st.integers(0, 2**32 - 1), N=st.integers(2, 7), L=st.integers(2, 4))
@settings(max_examples=40, deadline=None)
def test_trws_bound_is_monotone_and_below_the_optimum_with_conflicts(seed, N, L):
    m = random_mrf(np.random.default_rng(seed), N, L, p_edge=0.8, p_conf=0.6)
    opt = mrf.minimize(m, "exact").energy
    for penalty in (None, 0.0, 3.0):
        res = mrf.minimize(m, "trws", mrf.Options(conflict_penalty=penalty))
        bounds = np.array(res.stats["bounds"])
        assert np.all(np.diff(bounds) >= -1e-9)
        assert res.lower_bound == pytest.approx(bounds.max()) and res.lower_bound <= opt + 1e-9


@given(seed=st.integers(0, 2**32 - 1), N=st.integers(1, 8), L=st.integers(1, 4))
@settings(max_examples=40, deadline=None)
def test_lazy_flipper_never_ends_above_icm(seed, N, L):
    m = random_mrf(np.random.default_rng(seed), N, L)
    icm = mrf.minimize(m, "icm")
    for k in (2, 3):
        lf = mrf.minimize(m, "lazy_flipper", mrf.Options(max_flip=k))
        assert lf.energy <= icm.energy + 1e-12
        assert lf.stats["icm_energy"] == pytest.approx(icm.energy)


@given(seed=st.integers(0, 2**32 - 1), N=st.integers(1, 5), L=st.integers(1, 3))
@settings(max_examples=30, deadline=None)
def test_lazy_flipper_with_sets_as_large_as_the_problem_is_exact(seed, N, L):
    m = random_mrf(np.random.default_rng(seed), N, L)
    res = mrf.minimize(m, "lazy_flipper", mrf.Options(max_flip=N))
    assert res.energy == pytest.approx(mrf.minimize(m, "exact").energy, abs=1e-9)


def test_lazy_flipper_makes_a_swap_that_icm_cannot():
    # two robots want each other's cells; moving one at a time collides (same cell)
    unary = np.array([[1.0, 0.0], [0.0, 1.0]])
    mask = np.zeros((1, 2, 2), bool)
    mask[0, 0, 1] = mask[0, 1, 0] = False
    mask[0, 1, 1] = mask[0, 0, 0] = True  # both in one cell
    m = mrf.PairwiseMRF(unary, np.zeros((0, 2)), np.zeros((0, 2, 2)), [[0, 1]], mask, [0, 1])
    assert mrf.minimize(m, "icm").energy == pytest.approx(2.0)
    res = mrf.minimize(m, "lazy_flipper")
    assert res.labels.tolist() == [1, 0] and res.stats["moves"]["size_2"] == 1


def test_gibbs_is_reproducible_by_seed():
    m = swarm_mrf(60, seed=3)
    opts = mrf.Options(max_iter=30, temperature=1.0)
    a = mrf.minimize(m, "gibbs", opts)
    b = mrf.minimize(m, "gibbs", opts)
    assert np.array_equal(a.labels, b.labels) and a.stats["chain_energy"] == b.stats["chain_energy"]
    chains = {tuple(mrf.minimize(m, "gibbs", dataclasses.replace(opts, seed=s)).stats["chain_energy"])
              for s in range(4)}
    assert len(chains) > 1


@given(seed=st.integers(0, 2**32 - 1), N=st.integers(1, 7), L=st.integers(1, 4))
@settings(max_examples=30, deadline=None)
def test_gibbs_sampling_stays_feasible_and_is_greedy_when_cold(seed, N, L):
    rng = np.random.default_rng(seed)
    m = random_mrf(rng, N, L)
    x = m.initial.copy()
    for le in colour_sweep(m):
        sample_class(le, x, 1e3, rng)
        assert m.is_feasible(x)
    for le in colour_sweep(m):
        c = le.feasible_costs(x)
        y = x.copy()
        sample_class(le, y, 1e-300, rng)
        lo = c.min(axis=1)
        assert np.all(c[np.arange(le.nodes.size), y[le.nodes]] == lo)


def test_gibbs_hot_samples_cover_the_feasible_labels_uniformly():
    # one free node, 4 labels, label 3 forbidden by a neighbour fixed at its only label
    unary = np.array([[0.0, 1.0, 2.0, 3.0], [0.0, np.inf, np.inf, np.inf]])
    mask = np.zeros((1, 4, 4), bool)
    mask[0, 3, 0] = True
    m = mrf.PairwiseMRF(unary, np.zeros((0, 2)), np.zeros((0, 4, 4)), [[0, 1]], mask, [0, 0])
    le = [s for s in colour_sweep(m) if 0 in s.nodes][0]
    rng = np.random.default_rng(0)
    draws = []
    for _ in range(3000):
        x = m.initial.copy()
        sample_class(le, x, 1e9, rng)
        draws.append(x[0])
    freq = np.bincount(draws, minlength=4) / len(draws)
    assert freq[3] == 0 and np.all(np.abs(freq[:3] - 1 / 3) < 0.04)


@pytest.mark.parametrize("method", ["bp", "trws", "gibbs"])
def test_polish_never_hurts(method):
    m = swarm_mrf(80, seed=1)
    plain = mrf.minimize(m, method, mrf.Options(max_iter=20))
    polished = mrf.minimize(m, method, mrf.Options(max_iter=20, polish=True))
    assert polished.energy <= plain.energy + 1e-9 and "polish_moves" in polished.stats
    assert m.is_feasible(polished.labels)


@pytest.mark.parametrize("seed", range(3))
def test_swarm_problem_every_heuristic_is_feasible_and_above_the_bound(seed):
    m = swarm_mrf(120, seed=seed)
    results = {name: mrf.minimize(m, name, mrf.Options(max_iter=30)) for name in HEURISTIC}
    for name, res in results.items():
        check_result(m, res, name, max_iter=30)
    bound = max(results[n].lower_bound for n in WITH_BOUND if n in results)
    assert all(res.energy >= bound - 1e-9 for res in results.values())
    assert results["lazy_flipper"].energy <= results["icm"].energy + 1e-12


@given(seed=st.integers(0, 2**32 - 1), N=st.integers(2, 6), L=st.integers(1, 4))
@settings(max_examples=30, deadline=None)
def test_penalized_pairs_price_each_broken_conflict(seed, N, L):
    rng = np.random.default_rng(seed)
    m = random_mrf(rng, N, L)
    P = float(rng.uniform(0.5, 5.0))
    pairs, tables = penalized_pairs(m, P)
    key = np.sort(pairs, axis=1)
    assert len(np.unique(key, axis=0)) == len(key)
    for _ in range(10):
        x = rng.integers(0, m.n_labels)
        e_p = m.unary[np.arange(N), x].sum() + tables[np.arange(len(pairs)), x[pairs[:, 0]], x[pairs[:, 1]]].sum()
        assert e_p == pytest.approx(m.energy(x) + P * m.violated_conflicts(x).size)
    assert auto_penalty(m) >= 1.0


def test_broken_method_output_is_repaired_and_counted(monkeypatch):
    m = random_mrf(np.random.default_rng(0), 5, 3, p_conf=1.0, p_forbid=0.0)
    mask = np.ones_like(m.conflict_mask)
    mask[np.arange(len(mask)), m.initial[m.conflicts[:, 0]], m.initial[m.conflicts[:, 1]]] = False
    m = mrf.PairwiseMRF(m.unary, m.edges, m.pairwise, m.conflicts, mask, m.initial)
    bad = (m.initial + 1) % m.n_labels  # every conflict pair moves: broken where both moved

    def broken(mrf_, options):
        return mrf.MRFResult(labels=bad, energy=mrf_.energy(bad), energy_trace=np.zeros(1), iterations=1,
                             time_s=0.0, method="broken")

    caps = mrf.MRFCapabilities(optimal=False, lower_bound=False, exact_on_trees=False, monotone=False, stochastic=False)
    reg = Registry("MRF", [*mrf.METHODS, Backend(name="broken", entry=broken, capabilities=caps)])
    monkeypatch.setattr(mrf, "METHODS", reg)
    assert not m.is_feasible(bad)
    res = mrf.minimize(m, "broken")
    assert m.is_feasible(res.labels) and res.repaired > 0
    assert res.energy == pytest.approx(m.energy(res.labels))


@pytest.mark.parametrize("method", ["bp", "trws"])
def test_message_passing_counts_its_repairs(method):
    # without the penalty, messages ignore conflicts and decodings collide; repairs are counted
    found = False
    for seed in range(20):
        m = random_mrf(np.random.default_rng(seed), 6, 3, p_conf=1.0, p_forbid=0.5)
        res = mrf.minimize(m, method, mrf.Options(conflict_penalty=0.0, max_iter=10))
        check_result(m, res, method, max_iter=10)
        assert res.stats["repairs"] >= (res.repaired > 0)
        found |= res.stats["repairs"] > 0
    assert found


@pytest.mark.parametrize("method", HEURISTIC)
def test_time_limit_stops_early(method):
    m = swarm_mrf(100, seed=2)
    res = mrf.minimize(m, method, mrf.Options(time_limit=1e-9, max_iter=1000))
    check_result(m, res, method, max_iter=1000)
    assert res.iterations <= 1


def test_exact_refuses_big_problems_that_the_tests_skip():
    m = swarm_mrf(40)
    assert np.prod(m.n_labels.astype(float)) > MAX_LABELLINGS
    with pytest.raises(InvalidProblem):
        mrf.minimize(m, "exact")


@pytest.mark.parametrize("n, count", [(10, "740710656"), (11, r"about 5\.1e9"), (40, r"about 8\.7e34"),
                                      (100, r"about 2\.3e87")])
def test_exact_refusal_gives_the_count_readably(n, count):
    """The refusal's count of labellings is digits up to nine of them, else rounded: a tour's swarm of 100 was told
    of '1724333391924829996038697814307277425868800000000000000 labellings'."""
    m = swarm_mrf(n)
    with pytest.raises(InvalidProblem, match=rf"^exact: {count} labellings exceed the limit of {MAX_LABELLINGS};"):
        mrf.minimize(m, "exact")


@pytest.mark.parametrize("bad", [dict(temperature=0.0), dict(temperature=float("inf")), dict(schedule="fast"),
                                 dict(cooling=1.0), dict(cooling=0.0), dict(damping=1.0), dict(damping=-0.1),
                                 dict(conflict_penalty=-1.0), dict(conflict_penalty=float("inf")),
                                 dict(max_flip=0)])
def test_options_reject_out_of_range_values(bad):
    with pytest.raises(ValueError):
        mrf.Options(**bad)


@pytest.mark.parametrize("schedule", ["geometric", "log"])
def test_gibbs_schedules_cool(schedule):
    m = swarm_mrf(30, seed=4)
    res = mrf.minimize(m, "gibbs", mrf.Options(schedule=schedule, max_iter=20))
    assert res.stats["t_final"] < res.stats["t0"]
    check_result(m, res, "gibbs", max_iter=20)


def test_gibbs_survives_a_temperature_that_underflows_to_zero():
    m = random_mrf(np.random.default_rng(7), 5, 3)
    res = mrf.minimize(m, "gibbs", mrf.Options(max_iter=1200, cooling=0.5, temperature=1e3))
    assert res.stats["t_final"] == 0.0
    check_result(m, res, "gibbs", max_iter=1200)
    assert res.stats["chain_energy"][-1] >= mrf.minimize(m, "exact").energy - 1e-9
