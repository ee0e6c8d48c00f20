"""``result.json``'s ``solve_failures``: the windows with an attempt the QP backend ended without a solution for, read
from the status each rejection carries (:class:`~mrfswarm.continuous.receding_horizon.Rejection`; it was parsed back
from the rejection's text with a regex), not those the backend proved infeasible."""

from __future__ import annotations

import numpy as np
import pytest

from mrfswarm.config import SmoothingConfig, load_config
from mrfswarm.continuous.receding_horizon import RecedingHorizon, Rejection
from mrfswarm.pipeline import plan
from support.passing import GRID, PASSING, first_window
from support.repository import EXPERIMENTS


@pytest.mark.parametrize(("backend", "status"), [("piqp", "Status.PIQP_MAX_ITER_REACHED"), ("clarabel", None)])
def test_a_window_the_backend_does_not_solve_carries_its_status_and_one_it_proves_infeasible_none(backend, status):
    """Durations of 0.01 s with every limit row on: piqp runs out of iterations, clarabel proves it infeasible."""
    pytest.importorskip(backend)
    rh = RecedingHorizon(PASSING, GRID, SmoothingConfig(backend=backend), 0.25, workers=1)
    a, c, b, start, rec = first_window(rh)
    rh.limit_rows[a:b] = True
    sol, why = rh._solve(a, b, start, np.full(b - a, 0.01), rec)
    assert sol is None and isinstance(why, Rejection) and why.status == status, why
    assert why.startswith("2 robots: ") and ("infeasible" in why) == (status is None)
    rec.failed.append(f"nominal: {why}")
    rec.note_unsolved(why)
    assert rec.unsolved == ([] if status is None else [status])


def test_a_run_counts_the_windows_its_backend_did_not_solve():
    """A QP budget of one iteration: every window's attempts end out of iterations (and fly the witness)."""
    cfg = load_config(EXPERIMENTS / "free5.toml", ["simulation.enabled=false", "mrf.max_steps=6",
                                                   "smoothing.qp_options.max_iter=1"])
    result = plan(cfg, progress=False, workers=1)
    windows = result.continuous.windows
    assert all(w.unsolved == ["Status.PIQP_MAX_ITER_REACHED"] * len(w.failed) for w in windows), \
        [(w.failed, w.unsolved) for w in windows]
    # as result.json said it before: the status as the backend's error quotes it
    assert result.summary()["solve_failures"] == {"windows": len(windows), "statuses": ["Status.PIQP_MAX_ITER_REACHED"]}
