"""The Crazyflie memory: cflib's packing, decoded back and evaluated as the firmware does, and the report."""

import numpy as np
import pytest

from mrfswarm.config import load_config
from mrfswarm.errors import ExportError
from mrfswarm.pipeline import plan
from mrfswarm.trajectory.polynomial import PiecewisePolynomial
from support.repository import EXPERIMENTS

pytest.importorskip("cflib")
from mrfswarm.export import cflib_  # noqa: E402

TAUS = np.linspace(0.0, 1.0, 41)


@pytest.fixture(scope="module")
def corridor():
    """The corridor by default: 33 steps in 31 pieces (two pieces of two steps), which fit raw."""
    return plan(load_config(EXPERIMENTS / "corridor.toml", ["simulation.enabled=false"]), progress=False, workers=1)


@pytest.fixture(scope="module")
def corridor_per_step():
    """The corridor with one piece per step (smoothing.max_pieces = 0): 33 pieces, which do not fit raw."""
    return plan(load_config(EXPERIMENTS / "corridor.toml", ["simulation.enabled=false", "smoothing.max_pieces=0"]),
                progress=False, workers=1)


@pytest.fixture(scope="module")
def corridor_no_slack():
    """The corridor planned without the rows' room for the compressed rounding (EXPORT_SLACK = 0): control
    points on region edges, where nearest rounding leaves the regions."""
    from mrfswarm.continuous import receding_horizon

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(receding_horizon, "EXPORT_SLACK", 0.0)
        return plan(load_config(EXPERIMENTS / "corridor.toml", ["simulation.enabled=false"]), progress=False,
                    workers=1)


@pytest.fixture(scope="module")
def corridor_refined():
    """The corridor with refined step durations, whose robot 2's rounded speed landed on v_max exactly."""
    return plan(load_config(EXPERIMENTS / "corridor.toml", ["simulation.enabled=false", "smoothing.time_refinement=true"]),
                progress=False, workers=1)


def _limits(run):
    sm = run.config.smoothing
    return sm.v_max, sm.a_max, sm.j_max


def test_raw_pieces_are_cflibs_poly4d_and_float32_within_2_mm(corridor):
    from cflib.crazyflie.mem import Poly4D

    c = corridor.smoothed()
    alt = corridor.config.scenario.altitude
    for tr in c.trajectories:
        elements = cflib_.raw_pieces(tr, alt)
        assert all(isinstance(e, Poly4D) for e in elements) and len(elements) == tr.pieces
        data = cflib_.pack_raw(tr, alt)
        assert len(data) == cflib_.RAW_PIECE_BYTES * tr.pieces == len(b"".join(e.pack() for e in elements))
        s, x = cflib_.firmware_positions_raw(data, TAUS)  # the firmware's float32 Horner
        planned = tr.evaluate(tr.knots[:-1, None] + s.astype(float))
        err = np.linalg.norm(x[..., :2] - planned, axis=-1).max()
        assert err < 2e-3 and err < 1e-4  # measured some micrometres
        assert np.all(x[..., 2] == np.float32(alt))
        dec = cflib_.decode_raw(data, dim=2)  # the stored values, exactly as float32
        assert np.allclose(dec.durations, tr.durations, rtol=1e-7, atol=0)
        assert np.array_equal(dec.coefficients, tr.coefficients.astype(np.float32).astype(float))


def test_compressed_decodes_within_the_stated_margin_and_is_cflibs(corridor):
    from cflib.crazyflie.mem import CompressedSegment, CompressedStart

    c = corridor.smoothed()
    comp = cflib_.compress(c.trajectories, corridor.config.scenario.altitude, c.v_max, c.regions)
    assert comp.origin.tolist() == [20.0, 0.0, 0.0]  # the map reaches 40 m: shifted to whole metres
    blobs = [cflib_.pack_compressed(comp, i) for i in range(len(c.trajectories))]
    el = cflib_.compressed_elements(comp, 0)
    assert isinstance(el[0], CompressedStart) and all(isinstance(e, CompressedSegment) for e in el[1:])
    assert el[-1].duration == 0  # the end segment
    durations, fw = cflib_.firmware_positions_compressed(blobs, TAUS)
    for i, tr in enumerate(c.trajectories):
        assert len(blobs[i]) == comp.n_bytes(i) == 8 + 31 * tr.pieces + 3
        dec = cflib_.decode_compressed(blobs[i], comp.origin, dim=2)
        assert np.abs(dec.knots - tr.knots).max() <= 0.5e-3 + 1e-12  # knots rounded, not durations
        t = dec.knots[:-1, None] + durations[i][:, None].astype(float) * TAUS[None, :]
        exact = np.linalg.norm(dec.evaluate(t) - tr.evaluate(t), axis=-1).max()
        assert exact <= comp.position_error_bound  # proven in exact arithmetic
        xy = fw[i][..., :2].astype(float) + comp.origin[:2]
        firmware = np.linalg.norm(xy - tr.evaluate(t), axis=-1).max()
        deviation = np.linalg.norm(xy - dec.evaluate(t), axis=-1).max()
        assert firmware <= comp.position_error_bound + deviation
        assert deviation < 1e-3  # float32: measured 0.4 mm on this 40 m map
        assert np.all(np.abs(fw[i][..., 2] - 1.0) < 1e-6)


@pytest.mark.parametrize("which", ["corridor", "corridor_per_step"])
def test_compressed_rounding_stays_in_the_regions_and_limits(which, request):
    from mrfswarm.continuous.certificate import certify
    from mrfswarm.continuous.merge_pieces import step_times

    run = request.getfixturevalue(which)
    c = run.smoothed()
    assert (c.trajectories[0].pieces < len(c.knot_times) - 1) is (which == "corridor")
    alt = run.config.scenario.altitude
    for regions in (c.regions, None):
        comp = cflib_.compress(c.trajectories, alt, c.v_max, regions, c.knot_times, _limits(run))
        dec = [cflib_.decode_compressed(cflib_.pack_compressed(comp, i), comp.origin, 2)
               for i in range(len(c.trajectories))]
        steps = step_times(dec[0].knots, c.knot_times, c.piece_steps)  # the steps inside the rounded pieces
        cert = certify(dec, steps, c.regions, 2 * run.config.scenario.robot_radius, _limits(run))
        # nearest rounding puts points on region edges a hair outside, and a millimetre breaks the jerk limit
        # of 0.53 s steps (5.2 > 4 m/s^3); rounding into the regions and limits does neither
        assert cert.ok is (regions is not None), cert.problems
        if regions is None:
            assert any("jerk" in p for p in cert.problems)


def test_rounding_keeps_off_a_limit_it_would_only_touch(corridor_refined):
    """The rounding's limit check counted a rounded control point on the limit (2.0000000000004934 m/s against
    v_max 2, float noise) as within it; the certificate, computing the norms again from the decoded pieces, did
    not, and refused the robot's compressed flight. The check keeps a relative margin (INSIDE_LIMIT)."""
    from mrfswarm.export.crazyflie_memory import memory_report

    report, _ = memory_report(corridor_refined)
    comp = report["compressed"]
    assert comp["not_certified_robots"] == [] and comp["certificate"]["ok"] is True, comp["certificate"]["problems"]
    assert all(r["compressed_within_limits"] for r in report["robots"])


def test_the_plans_slack_keeps_nearest_rounding_in_the_regions(corridor, corridor_no_slack):
    """The rows' slack (EXPORT_SLACK) is what keeps rounded control points in their regions: without it nearest
    rounding leaves them by a hair; with it, it does not (the limits still need the region-aware search)."""
    from mrfswarm.continuous.certificate import certify
    from mrfswarm.continuous.merge_pieces import step_times

    leaves = {}
    for name, run in (("slack", corridor), ("none", corridor_no_slack)):
        c = run.smoothed()
        comp = cflib_.compress(c.trajectories, run.config.scenario.altitude, c.v_max, None)
        dec = [cflib_.decode_compressed(cflib_.pack_compressed(comp, i), comp.origin, 2)
               for i in range(len(c.trajectories))]
        cert = certify(dec, step_times(dec[0].knots, c.knot_times, c.piece_steps), c.regions,
                       2 * run.config.scenario.robot_radius, _limits(run))
        leaves[name] = any("leaves its region" in p for p in cert.problems)
    assert leaves == {"slack": False, "none": True}


def test_rounding_keeps_a_merged_pieces_steps_in_their_regions():
    """One piece over two steps whose split point lies on the edge of the first step's region: the rounding
    must keep the subdivided control points (not only the piece's own) inside."""
    from mrfswarm.continuous.certificate import certify
    from mrfswarm.continuous.regions import Regions

    coef = np.zeros((1, 8, 2))
    coef[0, 0] = [0.0003, 0.0004]
    coef[0, 1] = [0.3, 0.2]
    coef[0, 2] = [0.1, -0.05]
    piece = PiecewisePolynomial(np.array([2.0]), coef)
    knot_times = np.array([0.0, 0.8, 2.0])
    mid = piece.evaluate(np.array([0.8]))[0]
    lower = np.full((2, 1, 2), -1.0)
    upper = np.array([[[mid[0] + 1e-9, 1.0]], [[1.0, 1.0]]])
    regions = Regions(np.broadcast_to(np.eye(2), (2, 1, 2, 2)).copy(), lower, upper, np.zeros((2, 1), dtype=bool), 0.1)
    limits = (10.0, 10.0, 10.0)
    results = {}
    for name, reg in (("nearest", None), ("inside", regions)):
        comp = cflib_.compress([piece], 1.0, 1.0, reg, knot_times, limits)
        dec = cflib_.decode_compressed(cflib_.pack_compressed(comp, 0), comp.origin, 2)
        results[name] = certify([dec], knot_times, regions, 0.2, limits)
    assert not results["nearest"].ok and "leaves its region in step 0" in results["nearest"].problems[0]
    assert results["inside"].ok, results["inside"].problems


def test_report_per_robot_and_swarm(corridor, corridor_per_step):
    for run, pieces, fits in ((corridor, 31, True), (corridor_per_step, 33, False)):
        s = run.summary()
        cf = s["crazyflie"]
        assert cf["memory_bytes"] == 4096 and len(cf["robots"]) == 5
        for r in cf["robots"]:
            assert r["pieces"] == pieces and r["bytes_raw"] == pieces * 132 and r["fits_raw"] is fits
            assert r["bytes_compressed"] == 8 + pieces * 31 + 3 and r["fits_compressed"] is True
            assert r["compressed_certified"] is True and r["compressed_error_m"] <= cf["compressed"]["error_margin_m"]
        assert cf["max_pieces"] == pieces and cf["all_fit_raw"] is fits and cf["all_fit_compressed"] is True
        assert cf["compressed"]["certificate"]["ok"] is True and cf["compressed"]["not_certified_robots"] == []
        assert s["certificate"]["ok"] is True and s["pieces_per_robot"] == [pieces] * 5  # existing keys kept


def test_a_compressed_flight_that_leaves_its_regions_is_reported(corridor_no_slack, monkeypatch):
    """Break the region-aware rounding (nearest instead): the report must say the export is not certified, and
    why for each robot: its rounded control points leave its regions (clearance under the radius, by a hair), or
    (nearest rounding ignores the limits as well) its rounded jerk exceeds j_max."""
    real = cflib_.compress
    monkeypatch.setattr(cflib_, "compress", lambda trs, alt, v, regions=None, *rest: real(trs, alt, v, None))
    from mrfswarm.export.crazyflie_memory import memory_report

    report, _ = memory_report(corridor_no_slack)
    comp = report["compressed"]
    assert comp["certificate"]["ok"] is False and comp["certificate"]["problems"]
    assert comp["not_certified_robots"]
    bad = [r for r in report["robots"] if not r["compressed_certified"]]
    leaving = [r for r in bad if r["compressed_clearance_lower_bound_m"] < 0.25]
    assert leaving and any("leaves its region" in p for p in comp["certificate"]["problems"])
    assert all(r in leaving or r["compressed_within_limits"] is False for r in bad)
    assert min(r["compressed_clearance_lower_bound_m"] for r in bad) > 0.25 - 1e-3
    good = [r for r in report["robots"] if r["compressed_certified"]]
    assert all(r["compressed_within_limits"] and r["compressed_clearance_lower_bound_m"] >= 0.25 for r in good)
    # each robot's verdict is the certificate of its own rounded flight (regions and limits; the separation holds)
    from mrfswarm.continuous.certificate import certify
    from mrfswarm.continuous.merge_pieces import step_times

    c = corridor_no_slack.smoothed()
    comp = cflib_.compress(c.trajectories, corridor_no_slack.config.scenario.altitude, c.v_max, None)
    assert all(r["compressed_separation_lower_bound_m"] >= 0.5 for r in report["robots"])
    for i, r in enumerate(report["robots"]):
        dec = [cflib_.decode_compressed(cflib_.pack_compressed(comp, i), comp.origin, 2)]
        alone = certify(dec, step_times(dec[0].knots, c.knot_times, c.piece_steps), c.regions.window(0, c.regions.steps, np.array([i])), 0.5,
                        _limits(corridor_no_slack))
        assert r["compressed_certified"] is alone.ok, (i, alone.problems)
        assert r["compressed_within_limits"] is not any("control points reach" in p for p in alone.problems)


def test_flight_too_wide_is_refused_with_its_span():
    T = np.array([1.0])
    wide = [PiecewisePolynomial(T, np.array([[[0.0, 0.0], [70.0, 0.0]] + [[0.0, 0.0]] * 6]))]
    with pytest.raises(ExportError, match=r"spans 70\.000 m x 0\.000 m.*\+/-32\.767 m"):
        cflib_.compress(wide, 1.0, 70.0)
    fits = [PiecewisePolynomial(T, np.array([[[100.0, -50.0], [60.0, 0.0]] + [[0.0, 0.0]] * 6]))]
    c = cflib_.compress(fits, 1.0, 60.0)
    assert c.origin.tolist() == [130.0, -50.0, 0.0]
    assert np.abs(c.points_mm[0]).max() <= cflib_.INT16_MAX


def test_every_millimetre_survives_cflibs_truncating_encoder():
    from cflib.crazyflie.mem import CompressedStart

    for n in range(-cflib_.INT16_MAX, cflib_.INT16_MAX + 1, 7):
        data = CompressedStart(cflib_._metres(n), 0.0, 0.0, 0.0).pack()
        assert int.from_bytes(data[:2], "little", signed=True) == n


def test_decoders_reject_bad_data():
    with pytest.raises(ExportError, match="132-byte"):
        cflib_.decode_raw(b"\0" * 100)
    with pytest.raises(ExportError, match="end segment"):
        cflib_.parse_compressed(b"\0" * 8 + b"\x0f\x10\x00")


# --- 3-D flights: z is a polynomial of its own -------------------------------------------------------


@pytest.fixture(scope="module")
def flight3d():
    from support.flight3d import window_flight

    return window_flight(4, step_s=1.0)


def test_raw_pieces_of_a_3d_trajectory_carry_its_z(flight3d):
    from cflib.crazyflie.mem import Poly4D

    for tr in flight3d.trajectories:
        elements = cflib_.raw_pieces(tr, altitude=7.0)  # the altitude is for planar trajectories only
        assert all(isinstance(e, Poly4D) for e in elements)
        data = cflib_.pack_raw(tr, 7.0)
        s, x = cflib_.firmware_positions_raw(data, TAUS)
        planned = tr.evaluate(tr.knots[:-1, None] + s.astype(float))
        assert np.linalg.norm(x - planned, axis=-1).max() < 1e-4
        assert np.ptp(x[..., 2]) > 1.0  # z moves
        dec = cflib_.decode_raw(data, dim=3)
        assert np.array_equal(dec.coefficients, tr.coefficients.astype(np.float32).astype(float))


def test_a_3d_flight_compresses_with_its_z_points_and_decodes_within_the_bound(flight3d):
    from cflib.crazyflie.mem import CompressedStart

    trs = flight3d.trajectories
    v_max = max(float(np.linalg.norm(tr.evaluate(np.linspace(0, tr.duration, 4001), 1), axis=1).max()) for tr in trs)
    comp = cflib_.compress(trs, altitude=7.0, v_max=v_max)
    assert comp.dim == 3 and comp.z_mm is None and comp.origin.tolist() == [0.0, 0.0, 0.0]
    assert comp.points_mm[0].shape == (trs[0].pieces, 8, 3)
    blobs = [cflib_.pack_compressed(comp, i) for i in range(len(trs))]
    durations, fw = cflib_.firmware_positions_compressed(blobs, TAUS)
    for i, tr in enumerate(trs):
        assert len(blobs[i]) == comp.n_bytes(i) == 8 + 45 * tr.pieces + 3
        start = cflib_.compressed_elements(comp, i)[0]
        assert isinstance(start, CompressedStart)
        assert np.allclose([start.x, start.y, start.z], tr.evaluate(0.0), atol=1e-3)
        head, segments = cflib_.parse_compressed(blobs[i])
        assert all(len(pts[2]) == 7 and pts[3] == [] for _, pts in segments)  # z: 7 control points; yaw: none
        dec = cflib_.decode_compressed(blobs[i], comp.origin, dim=3)
        t = dec.knots[:-1, None] + durations[i][:, None].astype(float) * TAUS[None, :]
        assert np.linalg.norm(dec.evaluate(t) - tr.evaluate(t), axis=-1).max() <= comp.position_error_bound
        p = fw[i].astype(float) + comp.origin
        assert np.linalg.norm(p - dec.evaluate(t), axis=-1).max() < 1e-3  # the firmware's float32 (measured 0.12 mm)
        assert np.ptp(p[..., 2]) > 1.0
    assert comp.position_error_bound <= 0.5e-3 * np.sqrt(3) + v_max * 0.5e-3 + 1e-12


def test_a_3d_flight_too_high_moves_the_origin_in_z_and_too_tall_is_refused():
    T = np.array([1.0])
    high = [PiecewisePolynomial(T, np.array([[[1.0, 2.0, 40.0], [0.0, 0.0, 10.0]] + [[0.0, 0.0, 0.0]] * 6]))]
    c = cflib_.compress(high, 1.0, 10.0)
    assert c.origin.tolist() == [0.0, 0.0, 45.0] and np.abs(c.points_mm[0]).max() <= cflib_.INT16_MAX
    dec = cflib_.decode_compressed(cflib_.pack_compressed(c, 0), c.origin, dim=3)
    assert np.abs(dec.evaluate(np.linspace(0, 1, 11)) - high[0].evaluate(np.linspace(0, 1, 11))).max() < 2e-3
    tall = [PiecewisePolynomial(T, np.array([[[0.0, 0.0, 0.0], [0.0, 0.0, 70.0]] + [[0.0, 0.0, 0.0]] * 6]))]
    with pytest.raises(ExportError, match=r"z up to 70\.000 m.*\+/-32\.767 m"):
        cflib_.compress(tall, 1.0, 70.0)
    mixed = [high[0], PiecewisePolynomial(T, high[0].coefficients[..., :2])]
    with pytest.raises(ExportError, match=r"robot 1.*dimension 2 \(robot 0: 3\)"):
        cflib_.compress(mixed, 1.0, 10.0)


def test_rounding_keeps_a_3d_steps_control_points_in_their_regions():
    """One 3-D piece over two steps whose split point lies on the z edge of the first step's region: nearest
    rounding leaves it, the region-aware rounding (every axis) does not."""
    from mrfswarm.continuous.regions import Regions

    coef = np.zeros((1, 8, 3))
    coef[0, 0] = [0.0003, 0.0004, 0.0006]
    coef[0, 1] = [0.3, 0.2, 0.1]
    coef[0, 2] = [0.1, -0.05, 0.02]
    piece = PiecewisePolynomial(np.array([2.0]), coef)
    knot_times = np.array([0.0, 0.8, 2.0])
    mid = piece.evaluate(np.array([0.8]))[0]
    lower = np.full((2, 1, 3), -1.0)
    upper = np.ones((2, 1, 3))
    upper[0, 0, 2] = mid[2] + 1e-9
    regions = Regions(np.broadcast_to(np.eye(3), (2, 1, 3, 3)).copy(), lower, upper, np.zeros((2, 1), dtype=bool), 0.1)
    t0 = np.linspace(0.0, 0.8, 81)  # step 0, its end included
    top = {}
    for name, reg in (("nearest", None), ("inside", regions)):
        comp = cflib_.compress([piece], 1.0, 1.0, reg, knot_times, (10.0, 10.0, 10.0))
        dec = cflib_.decode_compressed(cflib_.pack_compressed(comp, 0), comp.origin, 3)
        top[name] = float(dec.evaluate(t0)[:, 2].max() - upper[0, 0, 2])
    assert top["nearest"] > 1e-5 and top["inside"] <= 0.0
