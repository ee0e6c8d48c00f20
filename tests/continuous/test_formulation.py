"""The window problem: one symbolic formulation, every QP backend, the NLP, and the corridors it needs."""

import numpy as np
import pytest
import scipy.sparse as sp

import solvers.qp
from mrfswarm.config import SmoothingConfig
from mrfswarm.continuous import RecedingHorizon, WindowFormulation
from mrfswarm.continuous.formulation import LIMIT_PARTS, hermite_trajectory, piece_maps
from mrfswarm.continuous.receding_horizon import MERGED_TIME_UNIT, WindowRecord, exact_min_separation
from mrfswarm.discrete.safety import discrete_violations
from mrfswarm.trajectory import integral_squared_derivative
from mrfswarm.trajectory.bernstein import control_points
from solvers.qp import Options
from support.passing import GRID, PASSING


def first_window(rh: RecedingHorizon, corridors: np.ndarray | None = None,
                 merged: np.ndarray | None = None) -> tuple[WindowFormulation, np.ndarray]:
    a, _, b = rh.windows()[0]
    start = np.zeros((rh.N, 4, 2))
    start[:, 0] = rh.X[0]
    pairs = np.flatnonzero(rh.seps.step < b) if corridors is None else corridors
    return WindowFormulation(rh._spec(a, b, np.arange(rh.N), start, pairs, merged=merged)), rh.nominal[a:b]


def test_the_scenario_is_a_legal_discrete_plan():
    assert discrete_violations(PASSING, GRID.free) == []


@pytest.mark.parametrize("degree, derivative", [(7, 4), (9, 4), (5, 3)])
def test_piece_maps_give_control_points_and_snap(degree, derivative):
    """The symbolic piece's coefficients reproduce Bernstein control points and the cost integral."""
    pm = piece_maps(degree, derivative)
    rng = np.random.default_rng(degree)
    T = np.array([0.6, 1.7])
    Y = rng.normal(size=(3, derivative, 2))
    B = rng.normal(size=(2, pm.nz - 2 * derivative, 2))
    traj = hermite_trajectory(Y, B, T, degree, derivative)
    k = pm.evaluate(T)
    for j in range(2):
        z = np.concatenate([Y[j], Y[j + 1], B[j]])  # (nz, 2), physical units (time scale 1)
        for r in range(4):
            rows = pm.rows[r]
            K = k[j * pm.size + pm.k_offset[r]: j * pm.size + pm.k_offset[r] + rows * pm.nz].reshape(pm.nz, rows).T
            parts = 1 if r == 0 else LIMIT_PARTS
            np.testing.assert_allclose(K @ z, control_points(traj, r, parts)[j], rtol=1e-9, atol=1e-9)
        H = k[j * pm.size + pm.h_offset:(j + 1) * pm.size].reshape(pm.nz, pm.nz)
        piece = hermite_trajectory(Y[j:j + 2], B[j:j + 1], T[j:j + 1], degree, derivative)
        cost = 0.5 * sum(z[:, d] @ H @ z[:, d] for d in range(2))
        assert cost == pytest.approx(integral_squared_derivative(piece, derivative), rel=1e-9)


def test_pack_and_unpack_are_inverse():
    rh = RecedingHorizon(PASSING, GRID, SmoothingConfig(), 0.25)
    form, _ = first_window(rh)
    x = np.random.default_rng(0).normal(size=form.n)
    np.testing.assert_allclose(form.pack(*form.unpack(x)), x, atol=1e-12)


REFERENCE = "cvxpy"
#: Every installed backend that takes inequality rows (cvxpy, the reference, solves with Clarabel:
#: the direct clarabel backend is compared with it through a different formulation path).
BACKENDS = [b for b in solvers.qp.BACKENDS.available(lambda c: c.inequalities) if b != REFERENCE]


@pytest.fixture(scope="module")
def window_qp():
    rh = RecedingHorizon(PASSING, GRID, SmoothingConfig(), 0.25)
    form, durations = first_window(rh)
    qp = form.qp(durations)
    ref = solvers.qp.solve(qp, REFERENCE, Options(eps_abs=1e-9, eps_rel=1e-9)) if REFERENCE in solvers.qp.available() \
        else pytest.skip("cvxpy (the reference) is not installed")
    return qp, ref


@pytest.mark.parametrize("backend", BACKENDS)
def test_every_backend_solves_the_window_qp_to_the_reference(window_qp, backend):
    qp, ref = window_qp
    sol = solvers.qp.solve(qp, backend, Options(eps_abs=1e-9, eps_rel=1e-9, max_iter=100_000))
    assert sol.objective == pytest.approx(ref.objective, rel=1e-5)
    assert qp.max_violation(sol.x) < 1e-5
    np.testing.assert_allclose(sol.x, ref.x, atol=1e-3 * np.abs(ref.x).max())


def test_duration_gradient_sums_as_the_sparse_products_do():
    """The gradient's precomputed terms (built once per formulation, which the window cache reuses) give the
    numbers of the plain sparse products credit @ (S @ dK), to the last bit: the time refinement follows a
    path that a last-bit change moves (a CLI test's L-BFGS-B refinement kept nothing after one). Corridor
    normals off the axes (coefficients other than +-1, where the order of a product shows) and merged pieces;
    any point (x, y) will do."""
    import dataclasses

    rh = RecedingHorizon(PASSING, GRID, SmoothingConfig(), 0.25)
    rh.merged_unit = MERGED_TIME_UNIT  # the merge rows scaled, as on fine cells
    a, _, b = rh.windows()[0]
    start = np.zeros((rh.N, 4, 2))
    start[:, 0] = rh.X[0]
    pairs = np.flatnonzero(rh.seps.step < b)
    merged = np.zeros(b - a - 1, dtype=bool)
    merged[2:4] = True
    rng = np.random.default_rng(5)
    for m in (None, merged):
        spec = rh._spec(a, b, np.arange(rh.N), start, pairs, merged=m)
        turn = rng.uniform(0.1, 0.5, len(spec.pair_normal))
        c, s_ = np.cos(turn), np.sin(turn)
        n = spec.pair_normal
        form = WindowFormulation(dataclasses.replace(
            spec, pair_normal=np.stack([c * n[:, 0] - s_ * n[:, 1], s_ * n[:, 0] + c * n[:, 1]], axis=1)))
        durations = rh.nominal[a:b] * rng.uniform(0.7, 1.5, b - a)
        x, y = 1e-5 * rng.normal(size=form.n), 1e5 * rng.normal(size=form.m)  # the rows' terms as large as the cost's
        pm = form.maps
        M, G = b - a, rh.N
        dk = pm.evaluate_derivative(form.normalized(durations))
        DK = sp.csc_matrix((dk.ravel(), np.arange(M * pm.size), np.arange(M + 1) * pm.size), shape=(M * pm.size + 1, M))
        ref = np.zeros((G, M))
        ai, ap, SA = form._A
        scale = form._row_scale(sp.csc_matrix((SA @ form._k(durations), ai, ap), shape=(form.m, form.n)))
        assert (scale is None) == (m is None)  # the merge rows are scaled in the QP: their multipliers back
        ys = y if scale is None else y * scale
        for (idx, ptr, S), half in ((form._A, False), (form._P, True)):
            cols = np.repeat(np.arange(len(ptr) - 1), np.diff(ptr))
            w = (0.5 * x[idx] if half else ys[idx]) * x[cols]
            credit = sp.csr_matrix((w, (cols // (form.dim * form.per_dim), np.arange(len(w)))), shape=(G, len(w)))
            ref += (credit @ (S @ DK)).toarray()
        ref *= form.spec.time_scale ** (-2 * form.spec.derivative)
        for _ in range(2):  # the terms built on the first call, reused on the second
            assert np.array_equal(form.duration_gradient(x, y, durations), ref)


@pytest.mark.parametrize("merge", [False, True])
def test_duration_gradient_is_the_derivative_of_the_optimal_snap(merge):
    """Envelope theorem: the gradient from the QP's multipliers matches finite differences of the optimum; with
    merged knots too, whose rows the QP scales (their multipliers scaled back: unscaled, the gradient was off)."""
    rh = RecedingHorizon(PASSING, GRID, SmoothingConfig(), 0.25)
    merged = None
    if merge:
        merged = np.zeros(rh.windows()[0][2] - 1, dtype=bool)
        merged[1:3] = True  # steps 1-3 one piece
        rh.merged_unit = MERGED_TIME_UNIT  # as on fine cells: the short unit, the merge rows scaled
    form, durations = first_window(rh, merged=merged)
    tight = Options(eps_abs=1e-10, eps_rel=1e-10)

    def optimum(d):
        sol = solvers.qp.solve(form.qp(d), "piqp", tight)
        return form.objective(sol.x, d), sol

    _, sol = optimum(durations)
    per_robot = form.duration_gradient(sol.x, sol.y, durations)
    assert per_robot.shape == (2, len(durations))
    grad = per_robot.sum(axis=0)
    for j in (0, 2, 6) if merge else (0, 3, 6):  # steps away from an active-set change (and, merged, where piqp
        # solves at 1e-10: at steps 1 and 3 +-1e-4 it ran to its iteration cap)
        # h = 1e-4 d: central differences' truncation error ~h^2 is far below the tolerance, while the optimum's
        # rounding (~1e-10 relative, divided by h) is not; at 1e-5 d it was 3e-3 relative with casadi 3.8.2
        h = 1e-4 * durations[j]
        up, down = durations.copy(), durations.copy()
        up[j] += h
        down[j] -= h
        fd = (optimum(up)[0] - optimum(down)[0]) / (2 * h)
        assert grad[j] == pytest.approx(fd, rel=2e-3)


def test_time_refinement_never_costs_more_than_the_qp():
    """The NLP over the durations (Ipopt), from the QP's: snap + weight x time no higher, and certified."""
    # from the slow cruise of the earlier default (1.25 m/s): a heavy weight on time then shortens the window
    rh = RecedingHorizon(PASSING, GRID, SmoothingConfig(time_refinement=True, speed=1.25), 0.25)
    a, c, b = rh.windows()[0]
    start = np.zeros((rh.N, 4, 2))
    start[:, 0] = rh.X[0]
    rec = WindowRecord(a, c, b)
    sol, _ = rh._solve(a, b, start, rh.nominal[a:b], rec)
    refined = rh._refine(sol, a, start, rec)
    w = rh.cfg.time_weight * rh.N
    assert rec.refined and not np.allclose(refined.durations, sol.durations)
    assert refined.cost + w * refined.durations.sum() < sol.cost + w * sol.durations.sum()
    assert refined.durations.sum() < sol.durations.sum()  # a heavy weight on time: a shorter window
    assert rh._certify(refined, a).ok


def test_the_relative_corridor_is_what_keeps_them_apart():
    """Mutation: without the pair's corridors the window's optimum brings the robots within 0.28 m."""
    # at a 1 m/s cruise, where the corridor binds (at 1.25 m/s it did with the octagon limits, 0.46 m without it;
    # the 16-gon's, which let a run along the grid fly at the limit, swing the robots out less there: 0.54 m)
    rh = RecedingHorizon(PASSING, GRID, SmoothingConfig(speed=1.0), 0.25)
    plan = rh.run()
    assert [w.attempt for w in plan.windows] == ["nominal"] * len(plan.windows)
    assert plan.certificate.ok and plan.min_separation >= 0.5 and rh.active.any()

    rh = RecedingHorizon(PASSING, GRID, SmoothingConfig(speed=1.0), 0.25)
    rh.seps = rh.seps.select(np.zeros(len(rh.seps), bool))  # drop the pair's corridors
    rh.active = np.zeros(0, bool)
    a, c, b = rh.windows()[0]
    start = np.zeros((2, 4, 2))
    start[:, 0] = rh.X[0]
    sol, _ = rh._solve(a, b, start, rh.nominal[a:b], WindowRecord(a, c, b))
    flights = [hermite_trajectory(sol.Y[i], sol.B[i], sol.durations, 7, 4) for i in range(2)]
    assert exact_min_separation(flights, 1.0) < 0.5
    assert not rh._certify(sol, a).ok  # and the certificate sees it
    plan = rh.run()  # the run stays safe: the window falls back until it is certified
    assert plan.windows[0].attempt != "nominal" and plan.certificate.ok and plan.min_separation >= 0.5


def test_the_linear_time_sparse_map_equals_the_sorting_one_and_falls_back_on_shared_positions():
    """``_distinct_sparse_map`` (SciPy's counting sort) gives the pattern and map of ``_sparse_map``;
    entries that share a position (which its shortcut cannot order) take ``_sparse_map``'s route."""
    from mrfswarm.continuous.formulation import _distinct_sparse_map, _sparse_map

    rng = np.random.default_rng(3)
    shape, n_k = (40, 30), 12
    positions = rng.choice(shape[0] * shape[1], 300, replace=False)
    rows, cols = positions % shape[0], positions // shape[0]
    kidx, coef = rng.integers(0, n_k, 300), rng.normal(size=300)
    k = rng.normal(size=n_k)
    rows_dup, cols_dup = np.concatenate([rows, rows[:50]]), np.concatenate([cols, cols[:50]])
    kidx_dup, coef_dup = np.concatenate([kidx, rng.integers(0, n_k, 50)]), np.concatenate([coef, rng.normal(size=50)])
    for args in ((rows, cols, kidx, coef), (rows_dup, cols_dup, kidx_dup, coef_dup)):
        (ai, ap, SA), (bi, bp, SB) = _distinct_sparse_map(*args, shape, n_k), _sparse_map(*args, shape, n_k)
        assert np.array_equal(ai, bi) and np.array_equal(ap, bp)
        np.testing.assert_allclose(SA @ k, SB @ k, rtol=1e-14, atol=1e-14)
    # and the sum of the duplicated entries is there (the matrix, not only its pattern)
    ai, ap, SA = _distinct_sparse_map(rows_dup, cols_dup, kidx_dup, coef_dup, shape, n_k)
    dense = np.zeros(shape)
    np.add.at(dense, (rows_dup, cols_dup), coef_dup * k[kidx_dup])
    np.testing.assert_allclose(sp.csc_matrix((SA @ k, ai, ap), shape=shape).toarray(), dense, atol=1e-13)
