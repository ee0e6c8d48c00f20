"""Windows long enough to brake in (``receding_horizon.braking_horizon``): every window ends at rest, so the steps it
plans and does not fly must hold the braking from the cruise. On fine cells 8 steps did not, and a flight at a
higher v_max flew later."""

from __future__ import annotations

import dataclasses

import pytest

import mrfswarm.continuous.receding_horizon as rhm
from mrfswarm.config import SmoothingConfig, load_config
from mrfswarm.continuous.receding_horizon import braking_horizon
from mrfswarm.continuous.time_grid import braking_distance
from mrfswarm.pipeline import plan

FINE = """[scenario]
map = { kind = "free", size = [40, 30], resolution = 0.1, origin = [0.05, 0.05] }
start = { positions = [[0.45, 1.25], [0.45, 1.75]] }
goal = [3.45, 1.55]
robot_radius = 0.04
"""
#: 5 m: 47 steps, more than a Crazyflie's 31 pieces, so its windows' pieces span several steps
FINE_LONG = FINE.replace("size = [40, 30]", "size = [60, 30]").replace("goal = [3.45, 1.55]", "goal = [5.45, 1.55]")


def test_the_horizon_holds_the_braking_in_its_unflown_steps():
    cfg = SmoothingConfig()  # v_max 2, a_max 4, j_max 4, horizon 8, execution 0.5
    assert braking_distance(2.0, 4.0, 4.0) == pytest.approx(2.0 * (2.0 / 4.0) ** 0.5, rel=1e-3)  # v sqrt(v / j)
    assert braking_horizon(cfg, 2.0, 1.0) == 8 and braking_horizon(cfg, 1.0, 0.25) == 8  # 1.4 m, 0.5 m: 8 hold it
    fine = braking_horizon(cfg, 2.0, 0.1)  # 1.41 m on 0.1 m cells
    assert fine == 36 and (fine - round(fine * cfg.execution)) * 0.1 >= rhm.BRAKING_ROOM * 1.41
    assert braking_horizon(dataclasses.replace(cfg, execution=0.75), 2.0, 0.1) == 72
    assert braking_horizon(dataclasses.replace(cfg, seam="rest"), 2.0, 0.1) == 8  # the paper's seams: as given
    assert braking_horizon(dataclasses.replace(cfg, horizon=50), 2.0, 0.1) == 50  # at least the config's


def _fly(tmp_path, *overrides):
    (tmp_path / "fine.toml").write_text(FINE)
    return plan(load_config(tmp_path / "fine.toml", ["simulation.enabled=false", *overrides]), progress=False)


def test_fine_cells_fly_sooner_at_a_higher_v_max(tmp_path, monkeypatch):
    """Two robots crossing 3 m of 0.1 m cells (27 steps): at v_max 2 in windows of 8 steps they flew 5.98 s, later
    than at v_max 1 (4.28 s); in windows of 36 steps 3.66 s, certified and without a stop."""
    fast = _fly(tmp_path)
    slow = _fly(tmp_path, "smoothing.v_max=1")
    assert fast.continuous.certificate.ok and fast.summary()["flight_quality"]["stops_per_robot"] == 0
    assert fast.continuous.makespan_s < slow.continuous.makespan_s
    assert fast.continuous.makespan_s < 4.0 and fast.continuous.v_max > 1.2  # 0.86 m/s at most in windows of 8
    monkeypatch.setattr(rhm, "BRAKING_ROOM", 0.0)  # windows of the configured 8 steps
    short = _fly(tmp_path)
    assert short.continuous.makespan_s > 1.4 * fast.continuous.makespan_s


def test_fine_cells_with_merged_pieces_fly_near_the_limits(tmp_path, monkeypatch):
    """The 5 m crossing in 31 pieces (a tour's): 13.0 s in windows of 8 steps, 18.9 s in windows of 36 whose merged
    pieces piqp could not solve (a feasible QP; its interior point stalled on the merge rows in the usual time unit).
    In the merged windows' own unit (MERGED_TIME_UNIT, merge rows scaled), 4.8 s, certified, within 31 pieces."""
    (tmp_path / "long.toml").write_text(FINE_LONG)
    r = plan(load_config(tmp_path / "long.toml", ["simulation.enabled=false"]), progress=False)
    c = r.continuous
    assert c.certificate.ok and max(c.pieces_per_robot) <= 31 and r.summary()["window_steps"] == 36
    assert any(len(w.piece_steps) < w.c - w.a for w in c.windows)  # merged pieces flown
    assert c.makespan_s < 6.0
    monkeypatch.setattr(rhm, "MERGED_TIME_UNIT", 1.0)
    assert plan(load_config(tmp_path / "long.toml", ["simulation.enabled=false"]), progress=False).continuous.makespan_s \
        > 2 * c.makespan_s


def test_a_user_s_own_long_windows_on_fine_cells_get_the_merged_time_unit(tmp_path):
    """The merged windows' time unit went only to windows the planner lengthened: the 5 m crossing in the user's own
    windows of 48 steps (``smoothing.horizon = 48``, enough to brake in) failed every profile and flew 37.5 s. The
    unit goes by the cells (FINE_BRAKING_STEPS): 5.0 s."""
    (tmp_path / "long.toml").write_text(FINE_LONG)
    r = plan(load_config(tmp_path / "long.toml", ["simulation.enabled=false", "smoothing.horizon=48"]), progress=False)
    c = r.continuous
    assert c.certificate.ok and max(c.pieces_per_robot) <= 31 and c.horizon == 48
    assert any(len(w.piece_steps) < w.c - w.a for w in c.windows)  # merged pieces flown
    assert c.makespan_s < 6.0
    cfg = SmoothingConfig()
    assert rhm.braking_steps(cfg, 2.0, 0.1) > rhm.FINE_BRAKING_STEPS >= rhm.braking_steps(cfg, 2.0, 1.0)
    assert rhm.FINE_BRAKING_STEPS >= rhm.braking_steps(cfg, 1.0, 0.25)  # the arena's cells are not fine
