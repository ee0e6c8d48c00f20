"""The multiplier scaling of a window's durations (mrfswarm.continuous.duration_scaling)."""

from __future__ import annotations

import numpy as np
import pytest

from mrfswarm.config import SmoothingConfig
from mrfswarm.continuous.duration_scaling import ScalingResult, scale_durations
from mrfswarm.continuous.receding_horizon import RecedingHorizon, WindowRecord
from solvers.nlp import NLPProblem
from support.attempts import unled
from support.passing import GRID, PASSING, first_window

Q = 4  # snap: each piece's cost scales as T^(1 - 2q) = T^-7
W = 3.0


def separable(c: np.ndarray, x0: np.ndarray, floor: np.ndarray | None = None, calls: list | None = None) -> NLPProblem:
    """f(T) = sum c T^-7 + W sum T; NaN below ``floor`` (no solution there, as a window QP)."""

    def fun(T):
        if calls is not None:
            calls.append(np.array(T))
        if floor is not None and np.any(T < floor):
            return float("nan")
        return float(np.sum(c * T ** (1 - 2 * Q)) + W * np.sum(T))

    def grad(T):
        if floor is not None and np.any(T < floor):
            return np.full(len(T), np.nan)
        return (1 - 2 * Q) * c * T ** (-2 * Q) + W

    return NLPProblem(fun, grad, x0, 1e-3, 100.0)


def first_allocation(rh: RecedingHorizon) -> tuple:
    """``first_window(rh)``, its QP solved with the gradient at the nominal durations, and the refinement's
    problem from there: (a, c, b, start, record, solution, allocation)."""
    a, c, b, start, rec = first_window(rh)
    sol, _ = rh._solve(a, b, start, rh.nominal[a:b], rec, gradient=True)
    assert sol is not None and sol.gradient is not None
    return a, c, b, start, rec, sol, rh.time_allocation(sol, a, start, rec)


def test_a_separable_cost_reaches_its_minimizer():
    """Each step's model is exact here: the iteration reaches T* = (7 c / W)^(1/8) within the gain tolerance."""
    c = np.array([0.5, 4.0, 40.0, 1e-3])
    best = ((2 * Q - 1) * c / W) ** (1 / (2 * Q))
    x0 = np.array([1.0, 1.0, 1.0, 1.0])
    out = scale_durations(separable(c, x0), W, Q, iterations=60, tol=1e-12)
    assert out.status == "converged" and out.iterations >= 3  # 1.76 = 1.25^2.5: three clipped steps at least
    assert out.x == pytest.approx(best, rel=1e-9)
    # longer where the cost presses (c large), shorter where it does not, from the same start
    assert out.x[2] > 1.0 > out.x[3]


def test_each_iteration_moves_a_step_by_at_most_the_clip():
    c = np.array([1e-6, 1e6])
    calls: list = []
    out = scale_durations(separable(c, np.ones(2), calls=calls), W, Q, iterations=1, clip=0.8)
    assert out.iterations == 1
    assert out.x == pytest.approx([0.8, 1.25])
    assert all(np.all(T >= 0.8 - 1e-12) and np.all(T <= 1.25 + 1e-12) for T in calls)


def test_a_total_caps_every_point_evaluated_and_time_moves_to_the_steps_that_press():
    """Step 0 presses (its minimizer is 2.35 s), step 1 costs little (0.26 s) and step 2 is between (1.21 s):
    free, the scaling ends at 3.83 s in sum; capped at the start's 3 s it never evaluates a longer point and ends
    with time moved from step 1 to step 0 (1.82, 0.21, 0.97), at a lower f than the start."""
    c = np.array([400.0, 1e-5, 2.0])
    x0 = np.ones(3)
    free = scale_durations(separable(c, x0), W, Q, iterations=60, tol=1e-12)
    assert free.x.sum() > 3.5
    calls: list = []
    out = scale_durations(separable(c, x0, calls=calls), W, Q, iterations=60, tol=1e-12, total=3.0)
    assert len(calls) > 3 and max(T.sum() for T in calls) <= 3.0 + 1e-9
    assert out.value < separable(c, x0).fun(x0)
    assert out.x[0] > 1.2 and out.x[1] < 0.8


def test_an_infeasible_trial_is_backtracked_and_never_kept():
    """Below 0.9 s the problem has no solution (NaN): the steps are halved and the result stays feasible."""
    c = np.array([1e-4, 1e-4, 1e-4])  # the minimizer (~0.25 s) lies in the infeasible part
    calls: list = []
    prob = separable(c, np.ones(3), floor=np.full(3, 0.9), calls=calls)
    out = scale_durations(prob, W, Q, iterations=20, backtracks=3)
    assert any(np.any(T < 0.9) for T in calls)  # it did try beyond the floor
    assert np.all(out.x >= 0.9) and np.isfinite(out.value) and out.value < prob.fun(np.ones(3))
    assert out.value == pytest.approx(prob.fun(out.x))
    # with no backtracks it stops at the first infeasible trial, keeping the last feasible point
    stop = scale_durations(separable(c, np.ones(3), floor=np.full(3, 0.9)), W, Q, iterations=20, backtracks=0)
    assert stop.status == "blocked" and np.all(stop.x >= 0.9)


def test_a_trial_that_raises_f_is_not_kept():
    """A cost steeper than the model (T^-15 read as T^-7) overshoots; f never rises along the accepted iterates."""
    values: list[float] = []

    def fun(T):
        f = float(np.sum(T ** -15.0) + W * np.sum(T))
        values.append(f)
        return f

    def grad(T):
        return -15.0 * T ** -16.0 + W

    prob = NLPProblem(fun, grad, np.full(2, 3.0), 1e-3, 100.0)
    out = scale_durations(prob, W, Q, iterations=30, clip=0.5, backtracks=4, tol=1e-9)
    assert out.value <= values[0] and out.value == pytest.approx(fun(out.x))
    assert max(values) > values[0] or out.iterations > 0


def test_a_first_step_pinned_by_the_start_state_is_held():
    """A window whose first step has no solution at any other duration (its start state pins it): the first
    iteration is blocked, then retried with that step held; the others reach their minimizer."""
    c = np.array([1e-3, 0.5, 40.0])

    def fun(T):
        if abs(T[0] - 1.0) > 1e-12:
            return float("nan")
        return float(np.sum(c * T ** (1 - 2 * Q)) + W * np.sum(T))

    def grad(T):
        return (1 - 2 * Q) * c * T ** (-2 * Q) + W

    out = scale_durations(NLPProblem(fun, grad, np.ones(3), 1e-3, 100.0), W, Q, iterations=60, tol=1e-12)
    assert out.status == "converged" and out.x[0] == 1.0
    assert out.x[1:] == pytest.approx(((2 * Q - 1) * c[1:] / W) ** (1 / (2 * Q)), rel=1e-9)


def test_an_infeasible_start_is_returned_unchanged():
    prob = separable(np.ones(2), np.full(2, 0.5), floor=np.full(2, 1.0))
    out = scale_durations(prob, W, Q)
    assert out.status == "infeasible start" and out.iterations == 0 and np.array_equal(out.x, [0.5, 0.5])


@pytest.mark.parametrize("kw", [{"clip": 1.0}, {"clip": 0.0}])
def test_bad_settings_are_refused(kw):
    with pytest.raises(ValueError, match="clip"):
        scale_durations(separable(np.ones(1), np.ones(1)), W, Q, **kw)




def test_the_window_refinement_by_scaling_is_the_nlps_at_a_fraction_of_the_qps(monkeypatch):
    """Two robots passing, from the slow 1.25 m/s cruise: the scaling lowers snap + weight x time to within
    0.5 % of Ipopt's optimum with under half its QP rounds (7 against 19; 8 against 39 before Ipopt searched
    only points no longer than the QP's, ``RecedingHorizon._not_longer``), certified, and without calling an
    NLP backend."""
    import solvers.nlp

    def window(refinement: str):
        # the weight of the measurements above (the default was 10 then, 20 since)
        rh = RecedingHorizon(PASSING, GRID, SmoothingConfig(time_refinement=True, speed=1.25, refinement=refinement,
                                                            time_weight=10.0),
                             0.25)
        a, c, b, start, rec = first_window(rh)
        sol, _ = rh._solve(a, b, start, rh.nominal[a:b], rec)
        rounds = rec.rounds
        refined = rh._refine(sol, a, start, rec)
        w = rh.cfg.time_weight * rh.N
        assert rec.refined and rh._certify(refined, a).ok
        assert refined.durations.sum() < sol.durations.sum()
        return refined.cost + w * refined.durations.sum(), rec.rounds - rounds

    nlp_value, nlp_rounds = window("nlp")

    def no_nlp(*args, **kwargs):
        raise AssertionError("the scaling refinement called an NLP backend")

    monkeypatch.setattr(solvers.nlp, "minimize", no_nlp)
    value, rounds = window("scaling")
    assert value == pytest.approx(nlp_value, rel=5e-3)
    assert rounds * 2 < nlp_rounds


def test_the_refinement_starts_from_the_accepted_qp_without_solving_it_again(monkeypatch):
    """A window solved with its gradient (as the attempts are when time_refinement is on) is the refinement's start
    point: evaluating f and its gradient there solves no QP, and they are what a fresh solve at the same durations
    gives."""
    rh = RecedingHorizon(PASSING, GRID, SmoothingConfig(time_refinement=True, speed=1.25), 0.25)
    a, c, b, start, rec, sol, alloc = first_allocation(rh)
    solves: list = []
    real = RecedingHorizon._solve
    monkeypatch.setattr(RecedingHorizon, "_solve", lambda self, *args, **kw: solves.append(1) or real(self, *args, **kw))
    x0 = np.array(alloc.problem.x0)
    f0, g0 = alloc.problem.fun(x0), alloc.problem.grad(x0)
    assert solves == []
    fresh = alloc.problem.fun(x0 * (1 + 1e-12))  # another point: a solve, from the same rows
    assert solves == [1]
    again = rh._solve(a, b, start, x0.copy(), WindowRecord(a, c, b), gradient=True)[0]
    assert again is not None and again.gradient is not None
    assert f0 == pytest.approx(fresh, rel=1e-6)
    np.testing.assert_allclose(g0, again.gradient + alloc.weight, rtol=1e-4, atol=1e-6 * np.abs(g0).max())


@pytest.mark.parametrize("shorter, refined", [(0.0, False), (1e-6, True)], ids=["rounding", "a microsecond"])
def test_the_qps_durations_but_for_rounding_are_no_refinement(monkeypatch, shorter, refined):
    """The scaling's cap at the QP's sum can leave a point whose steps differ from the QP's by rounding alone
    (6e-17 s on the refined arena's third window), where the QP solved again is lower by its tolerance: that is
    the QP's own durations, kept as they were and not counted in ``refined_windows``. Steps a microsecond shorter
    are a refinement."""
    import mrfswarm.continuous.receding_horizon as rh_mod

    rh = RecedingHorizon(PASSING, GRID, SmoothingConfig(time_refinement=True, speed=1.25), 0.25, workers=1)
    a, c, b, start, rec = first_window(rh)
    sol, _ = rh._solve(a, b, start, rh.nominal[a:b], rec, gradient=True)
    assert sol is not None and sol.gradient is not None and rh._shortens_flown(sol, rec)
    point = sol.durations.copy()
    point[1:-1] = np.nextafter(point[1:-1] - shorter, 0.0)  # one ulp shorter still: what the cap's rounding leaves
    # the QP there: the same trajectories, lower by a solver's tolerance
    monkeypatch.setattr(rh, "_solve", lambda a, b, start, T, rec, **kw: (
        rh_mod._Solution(sol.Y, sol.B, np.array(T), sol.cost * (1 - 1e-8), sol.gradient), ""))

    def scaling(problem, weight, derivative, total=None):
        return ScalingResult(point, problem.fun(point), 1, 2, "converged")

    monkeypatch.setattr(rh_mod, "scale_durations", scaling)
    out = rh._refine(sol, a, start, rec)
    assert rec.refined is refined and (out is not sol) is refined
    assert (rh.unrefined is not None) is refined  # nothing for the next window's undo to take back


def test_a_backend_without_multipliers_still_solves_the_window(monkeypatch):
    """The attempts ask for the gradient when time_refinement is on; a QP backend that gives no multipliers must
    still fly the window (its solution has no gradient, and the refinement then keeps it)."""
    import mrfswarm.continuous.receding_horizon as rh_mod

    real = rh_mod.solve_window

    def no_multipliers(spec, durations, backend, options, gradient=False):
        out = real(spec, durations, backend, options, gradient=False)
        return out if isinstance(out, str) else (*out[:3], None)

    monkeypatch.setattr(rh_mod, "solve_window", no_multipliers)
    rh = RecedingHorizon(PASSING, GRID, SmoothingConfig(time_refinement=True, speed=1.25), 0.25, workers=1)
    a, c, b, start, rec = first_window(rh)
    sol, why = rh._solve(a, b, start, rh.nominal[a:b], rec, gradient=True)
    assert why == "" and sol is not None and sol.gradient is None
    assert rh._refine(sol, a, start, rec) is sol and not rec.refined


def test_the_optimistic_profiles_get_a_third_of_the_iteration_budget(monkeypatch):
    """The fast (and its slower variants), bold, jerk-limited start and moderate attempts (and the stretch's probe)
    run PIQP at 40 of its 120 iterations, the cautious one at the full budget.

    Solves given the smaller budget are made to fail here: the window then flies the cautious profile, and every
    solve of it had the stage's full options."""
    import mrfswarm.continuous.receding_horizon as rh_mod
    import solvers.qp

    cap = solvers.qp.BACKENDS.get("piqp").capabilities.iteration_cap
    assert cap and cap > 3
    budgets: list[int] = []
    solve = rh_mod.solve_window

    def spy(spec, durations, backend, options, gradient=False):
        budgets.append(options.max_iter)
        if options.max_iter < rh_mod.QP_OPTIONS.max_iter:
            return "iteration budget of the optimistic attempts"
        return solve(spec, durations, backend, options, gradient)

    monkeypatch.setattr(rh_mod, "solve_window", spy)
    unled(monkeypatch)
    rh = RecedingHorizon(PASSING, GRID, SmoothingConfig(), 0.25, workers=1)
    assert [name for name, _, _ in rh_mod.PROFILES] == ["fast", "nominal", "moderate", "cautious"] and rh.profiles
    a, c, b, start, _ = first_window(rh)
    _, rec = rh._plan_window(a, c, b, start, None)
    assert rec.attempt == "cautious"
    # the stretch's probe (the window without limit rows) runs the smaller budget too, and failing adds no attempt
    slower = [f"fast x{f:g}" for f in rh_mod.FAST_SLOWER]
    # the flight's first window: the jerk-limited start too, between the bold and the moderate profile here
    assert [f.split(":")[0] for f in rec.failed] == ["fast", *slower, "nominal", rh_mod.JERK_START_NAME, "moderate",
                                                     "stretch"]
    n = 5 + len(slower)
    assert budgets[:n] == [int(np.ceil(cap / 3))] * n
    assert set(budgets[n:]) == {rh_mod.QP_OPTIONS.max_iter}


@pytest.mark.parametrize("refinement, budget", [("scaling", 30), ("nlp", 40)])
def test_the_refinements_trial_points_get_the_smaller_budget(monkeypatch, refinement, budget):
    """The scaling's trial points run a quarter of PIQP's 120 iterations, the NLP backend's the attempts' third (at a
    quarter, Ipopt's line search met more points without a solution)."""
    import mrfswarm.continuous.receding_horizon as rh_mod

    budgets: dict[bool, set] = {True: set(), False: set()}
    solve = rh_mod.solve_window

    def spy(spec, durations, backend, options, gradient=False):
        budgets[gradient].add(options.max_iter)
        return solve(spec, durations, backend, options, gradient)

    monkeypatch.setattr(rh_mod, "solve_window", spy)
    cfg = SmoothingConfig(time_refinement=True, speed=1.25, refinement=refinement, nlp="slsqp")
    rh = RecedingHorizon(PASSING, GRID, cfg, 0.25, workers=1)
    a, c, b, start, rec = first_window(rh)
    sol, _ = rh._solve(a, b, start, rh.nominal[a:b], rec)
    rh._refine(sol, a, start, rec)
    assert budgets[False] == {rh_mod.QP_OPTIONS.max_iter}  # the window's own solve (no profiles: speed given)
    assert budgets[True] == {budget}


def test_the_iteration_budget_is_the_smaller_of_the_cap_and_max_iter():
    from solvers.qp import QPCapabilities

    capped = QPCapabilities(inequalities=True, warm_start=False, detects_infeasibility=True, sparse=True,
                            iteration_cap=120)
    assert capped.iteration_budget(50000) == 120 and capped.iteration_budget(30) == 30
    free = QPCapabilities(inequalities=True, warm_start=True, detects_infeasibility=True, sparse=True)
    assert free.iteration_budget(50000) == 50000  # a first-order method runs what it is given
    assert "iteration_cap=120" in capped.flags() and "warm_start" not in capped.flags()


def test_a_window_whose_flown_steps_the_scaling_would_only_lengthen_is_not_refined(monkeypatch):
    """The scaling's first step is read off the accepted QP's gradient: where it lengthens every flown step, the
    window is kept as it is without a QP solve (its refinement could only move time within the tail, planned
    again by the next window); where it shortens one, the refinement runs."""
    import dataclasses

    rh = RecedingHorizon(PASSING, GRID, SmoothingConfig(time_refinement=True, speed=1.25), 0.25, workers=1)
    a, c, b, start, rec = first_window(rh)
    sol, _ = rh._solve(a, b, start, rh.nominal[a:b], rec, gradient=True)
    assert sol is not None and sol.gradient is not None and 0 < c - a < b - a
    w = rh.cfg.time_weight * rh.N
    q = rh.cfg.derivative
    solves: list = []
    real = RecedingHorizon._solve
    monkeypatch.setattr(RecedingHorizon, "_solve", lambda self, *args, **kw: solves.append(1) or real(self, *args, **kw))
    # -dJ/dT_j = w s^(2q): the scaling's model asks step j for s times its duration
    press = np.full(b - a, w * 0.9 ** (2 * q))
    press[:c - a] = w * 1.2 ** (2 * q)  # the flown steps press: longer, even capped at the sum
    kept = rh._refine(dataclasses.replace(sol, gradient=-press), a, start, rec)
    assert kept.gradient is not None and np.array_equal(kept.gradient, -press)
    assert solves == [] and not rec.refined
    press[:c - a], press[c - a:] = w * 0.9 ** (2 * q), w * 1.2 ** (2 * q)  # the tail presses: flown steps shorter
    rh._refine(dataclasses.replace(sol, gradient=-press), a, start, rec)
    assert solves  # the refinement ran its trial points


def test_a_trial_point_starts_from_the_rows_of_the_best_point_so_far(monkeypatch):
    """The window's QP at a trial point starts from the lazy rows of the best point solved so far (the lowest f):
    rows a neighbouring point needed are likely needed again, and need not be found again, one more round each.
    A trial without a solution (here one that switched many limit rows on) passes on nothing."""
    rh = RecedingHorizon(PASSING, GRID, SmoothingConfig(time_refinement=True, horizon=4, speed=1.32, time_weight=10.0),
                         0.25, workers=1)
    a, c, b, start, rec, sol, alloc = first_allocation(rh)
    entry: list = []
    real = RecedingHorizon._solve

    def spy(self, *args, **kw):
        entry.append((self.active.copy(), self.limit_rows.copy()))
        return real(self, *args, **kw)

    monkeypatch.setattr(RecedingHorizon, "_solve", spy)
    f0 = alloc.problem.fun(sol.durations)
    better = sol.durations * np.array([1.22, 1.035, 0.92, 0.91])
    rounds = rec.rounds
    f1 = alloc.problem.fun(better)
    assert np.isfinite(f1) and f1 < f0
    assert rec.rounds - rounds == 2  # the accepted QP's rows lacked one corridor
    best_rows = alloc.rows[better.tobytes()]
    assert best_rows[0].sum() > alloc.base[0].sum()
    assert np.isnan(alloc.problem.fun(sol.durations * 0.97))  # no solution: it switched limit rows on
    assert rh.limit_rows.sum() > best_rows[1].sum()
    rounds = rec.rounds
    f2 = alloc.problem.fun(sol.durations * np.array([1.25, 1.05, 0.95, 0.95]))
    assert np.isfinite(f2)
    assert rec.rounds - rounds == 1  # the corridor the best point needed was on from the start
    for got, want in zip(entry[-1], best_rows):
        np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize("longer, kept", [(4e-16, True), (1e-3, False)])
def test_a_refined_point_longer_by_rounding_only_is_kept(monkeypatch, longer, kept):
    """The refinement keeps no point that lasts longer than the QP's durations, and the scaling caps its points at
    their sum, which rounding can pass by an ulp: such a point counts as no longer (refined clutter40 lost two
    windows' refinements to it), one 1 ms longer does not."""
    import mrfswarm.continuous.receding_horizon as rh_mod

    rh = RecedingHorizon(PASSING, GRID, SmoothingConfig(time_refinement=True, speed=1.25), 0.25, workers=1)
    a, c, b, start, rec, sol, alloc = first_allocation(rh)
    total = sol.durations.sum()
    found = scale_durations(alloc.problem, alloc.weight, rh.cfg.derivative, total=total)
    T = found.x * (total / found.x.sum())
    T[-1] += total * longer  # the cap's point, past the QP's sum by ``longer``
    assert T.sum() > total and alloc.problem.fun(T) < alloc.problem.fun(sol.durations)

    def only(problem, weight, derivative, **kw):  # the scaling, had it stopped at that point
        return ScalingResult(T, problem.fun(T), 1, 1, "converged")

    monkeypatch.setattr(rh_mod, "scale_durations", only)
    refined = rh._refine(sol, a, start, rec)
    assert rec.refined == kept
    assert np.array_equal(refined.durations, T if kept else sol.durations)


@pytest.mark.parametrize("nlp, rows", [("ipopt", 1), ("slsqp", 1), ("lbfgsb", 0)])
def test_the_nlp_refinement_searches_no_point_longer_than_the_qps(monkeypatch, nlp, rows):
    """The NLP refinement keeps no point that lasts longer in sum than the window's QP, so a backend that takes
    linear rows gets that one, sum(T) <= the QP's sum (the scaling's cap); L-BFGS-B, bounds only, gets none and is
    still run. The refined window is certified and no longer."""
    import solvers.nlp

    seen: list = []
    minimize = solvers.nlp.minimize
    monkeypatch.setattr(solvers.nlp, "minimize", lambda problem, backend, options=None: seen.append(problem)
                        or minimize(problem, backend, options))
    rh = RecedingHorizon(PASSING, GRID, SmoothingConfig(time_refinement=True, speed=1.25, refinement="nlp", nlp=nlp),
                         0.25)
    a, c, b, start, rec = first_window(rh)
    sol, _ = rh._solve(a, b, start, rh.nominal[a:b], rec, gradient=True)
    refined = rh._refine(sol, a, start, rec)
    assert len(seen) == 1 and seen[0].A.shape == (rows, len(sol.durations))
    if rows:
        assert np.all(seen[0].A == 1.0) and seen[0].ub[0] == pytest.approx(sol.durations.sum(), abs=0)
    assert rh._certify(refined, a).ok and refined.durations.sum() <= sol.durations.sum() + 1e-9
