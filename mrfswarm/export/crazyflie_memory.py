"""What a plan takes in the Crazyflies' trajectory memory, and whether its compressed form is still safe.

The ``crazyflie`` section of ``result.json`` (:func:`memory_report`): per robot, its pieces
and their bytes in the raw and the compressed format (packed by ``cflib``,
:mod:`mrfswarm.export.cflib_`) and whether each fits the 4096-byte memory; for the swarm,
the largest of those and whether all fit; per robot the format that flies it (``flies``: raw where
its pieces fit, else compressed where those fit and certify, else none) and, where a robot fits
neither, ``advice``: one line saying why and what to plan instead (:func:`advice`), which ``mrfswarm
run`` and the flight scripts say too.

The compressed format rounds control points to millimetres and knots to milliseconds,
so the plan's certificate does not carry over by itself. Here the flight the compressed
bytes stand for (decoded in exact arithmetic, :func:`~mrfswarm.export.cflib_.decode_compressed`)
is certified anew by the continuous stage's own function,
:func:`~mrfswarm.continuous.certificate.certify`, on the plan's regions, safety distance
and limits: all robots share the rounded knots, so piece j of every robot still flies the
same steps; a piece spanning several steps is split at their times moved with the
piece's rounding (:func:`~mrfswarm.continuous.merge_pieces.step_times`: the same fractions
of the piece as planned), and the proof holds step by step as it stands. A compressed flight that fails it is reported so,
with the lower bounds it does have: per robot, clearance >= radius - sqrt(d) x (largest slab
violation of its control points: a region is d orthonormal slabs, so a point that far
outside all of them is sqrt(d) times as far from the region) and separation >= the exact distance
of its nearest relative hull. What is not proven: the firmware's float32 arithmetic,
measured instead (``float32_deviation_m``, sampled, against the exact decoding).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from mrfswarm.errors import ExportError
from mrfswarm.export import cflib_

if TYPE_CHECKING:
    from mrfswarm.pipeline import Result

SAMPLES_PER_PIECE = 16
"""Samples per piece of the measured float32 errors."""


def memory_report(result: Result) -> tuple[dict[str, Any] | None, cflib_.Compressed | None]:
    """The ``crazyflie`` section of ``result.json`` (None without a continuous plan) and the
    compressed flight it certifies (None if there is none).

    Without ``cflib`` installed the section is ``{"error": "..."}`` (what to install): the
    sizes are ``cflib``'s packing, not a formula of ours.
    """
    if result.continuous is None:
        return None, None
    try:
        cflib_.cflib_mem()
    except ExportError as e:
        return {"error": str(e)}, None
    c = result.continuous
    cfg = result.config
    altitude = cfg.scenario.altitude
    trs = c.trajectories
    taus = np.linspace(0.0, 1.0, SAMPLES_PER_PIECE)
    robots: list[dict[str, Any]] = []
    for i, tr in enumerate(trs):
        raw = cflib_.pack_raw(tr, altitude)
        s, x = cflib_.firmware_positions_raw(raw, taus)
        planned = tr.evaluate(tr.knots[:-1, None] + s.astype(float))
        robots.append({"robot": i, "pieces": tr.pieces, "bytes_raw": len(raw),
                       "fits_raw": len(raw) <= cflib_.MEMORY_BYTES,
                       "raw_float32_error_m": float(np.linalg.norm(x[..., :tr.dim] - planned, axis=-1).max())})
    out: dict[str, Any] = {
        "memory_bytes": cflib_.MEMORY_BYTES,
        "max_pieces": max(r["pieces"] for r in robots),
        "max_bytes_raw": max(r["bytes_raw"] for r in robots),
        "all_fit_raw": all(r["fits_raw"] for r in robots),
        "max_raw_float32_error_m": max(r["raw_float32_error_m"] for r in robots),
    }
    comp = None
    try:
        compressed, comp = _compressed(result, taus, robots)
    except ExportError as e:  # the flight does not fit the format: say so, per robot too
        for r in robots:
            r.update({"bytes_compressed": None, "fits_compressed": False, "compressed_certified": False})
        out.update({"max_bytes_compressed": None, "all_fit_compressed": False, "compressed": {"error": str(e)}})
    else:
        out.update({"max_bytes_compressed": max(r["bytes_compressed"] for r in robots),
                    "all_fit_compressed": all(r["fits_compressed"] for r in robots),
                    "compressed": compressed})
    for r in robots:
        r["flies"] = "raw" if r["fits_raw"] else \
            "compressed" if r["fits_compressed"] and r["compressed_certified"] else None
    out["robots"] = robots
    out["advice"] = advice(out, cfg.smoothing.max_pieces)
    return out, comp


def advice(section: dict[str, Any], max_pieces: int) -> str | None:
    """One line for the robots of a ``crazyflie`` section that no format flies (None if there are none):
    how much they take raw, why the compressed format does not hold them, and what to plan instead.

    More pieces than 31 do not fit raw, and a longer flight needs more: a run that left the piece limit
    off (``smoothing.max_pieces`` = 0, or above 31) plans again with it; one that had it flies too long."""
    robots = [r for r in section["robots"] if r["flies"] is None]
    if not robots:
        return None
    who = [r["robot"] for r in robots]
    names = f"robot {who[0]}" if len(who) == 1 else \
        f"robots {', '.join(map(str, who[:8]))}{' ...' if len(who) > 8 else ''} ({len(who)} of {len(section['robots'])})"
    raw = max(robots, key=lambda r: r["bytes_raw"])
    compressed = section["compressed"]
    if "error" in compressed:
        why = f"the compressed format holds none ({compressed['error']})"
    elif not all(r["fits_compressed"] for r in robots):
        why = f"compressed up to {max(r['bytes_compressed'] for r in robots)} bytes"
    else:
        why = "their compressed flight is not certified (crazyflie.compressed.not_certified_robots)"
    raw_pieces = cflib_.MEMORY_BYTES // cflib_.RAW_PIECE_BYTES
    if max_pieces == 0 or max_pieces > raw_pieces:
        instead = (f"plan again with smoothing.max_pieces = {raw_pieces} (the default: steps merged into at most "
                   f"{raw_pieces} pieces where they can be), or a shorter flight")
    else:
        instead = ("plan a shorter flight (a nearer goal: a long way flown as legs, each a run that starts where "
                   "the last one ended)")
    one = len(who) == 1  # "robot 1 fit no ... refuse them" (a 3-D tour)
    return (f"{names} fit{'s' * one} no Crazyflie trajectory memory ({cflib_.MEMORY_BYTES} bytes): raw "
            f"{'' if one else 'up to '}{raw['pieces']} pieces, {raw['bytes_raw']} bytes (at most {raw_pieces} pieces "
            f"fit), {why}; fly.py and cflib_upload.py refuse {'it' if one else 'them'}: {instead}")


def _compressed(result: Result, taus: np.ndarray,
                robots: list[dict[str, Any]]) -> tuple[dict[str, Any], cflib_.Compressed]:
    """Pack, decode and certify the compressed flight; fill each robot's entry, return the swarm's."""
    from mrfswarm.continuous.certificate import certify, control_point_stack, hull_distance_from_origin
    from mrfswarm.continuous.merge_pieces import step_pieces, step_times
    from mrfswarm.continuous.regions import near_pairs
    from mrfswarm.geometry import downwash_scale

    c = result.smoothed()
    cfg = result.config
    radius = cfg.scenario.robot_radius
    distance = 2 * radius
    sm = cfg.smoothing
    limits = (sm.v_max, sm.a_max, sm.j_max)
    comp = cflib_.compress(c.trajectories, cfg.scenario.altitude, c.v_max, c.regions, c.knot_times, limits)
    blobs = [cflib_.pack_compressed(comp, i) for i in range(len(robots))]
    dim = comp.dim
    decoded = [cflib_.decode_compressed(b, comp.origin, dim=dim) for b in blobs]
    # the steps' times within the rounded knots (pieces may span several steps)
    piece_steps = np.arange(len(c.knot_times)) if c.piece_steps is None else c.piece_steps
    steps = step_times(decoded[0].knots, c.knot_times, piece_steps) \
        if len(decoded[0].knots) == len(piece_steps) else decoded[0].knots
    scale = downwash_scale(dim, cfg.scenario.downwash)  # separation in the downwash-scaled metric, as planned
    cert = certify(decoded, steps, c.regions, distance, limits, scale)

    # the firmware's float32 maths against the exact decoding, and against the plan
    durations, fw = cflib_.firmware_positions_compressed(blobs, taus)
    deviation, error = np.zeros(len(robots)), np.zeros(len(robots))
    for i, (tr, dec) in enumerate(zip(c.trajectories, decoded)):
        t = dec.knots[:-1, None] + durations[i][:, None].astype(float) * taus[None, :]
        p = fw[i][..., :dim].astype(float) + comp.origin[:dim]
        deviation[i] = np.linalg.norm(p - dec.evaluate(t), axis=-1).max()
        error[i] = np.linalg.norm(p - tr.evaluate(t), axis=-1).max()

    # per robot: the certificate's checks, attributed
    split = step_pieces(decoded, steps)  # one piece per step, as the certificate checks them
    on_grid = not isinstance(split, str)
    clearance = np.full(len(robots), radius)
    separation = np.full(len(robots), distance)
    within = np.ones(len(robots), dtype=bool)
    if not isinstance(split, str):
        cps = control_point_stack(split)
        P = cps[0]
        slab = c.regions.violation(P.transpose(1, 0, 2, 3)).max(axis=0)  # (N,)
        clearance = radius - np.sqrt(dim) * slab
        for r, lim in zip(cps[1:], limits):
            within &= np.linalg.norm(r, axis=-1).max(axis=(1, 2)) <= lim
        S = P * scale
        lo, hi = S.min(axis=2), S.max(axis=2)
        for j in range(P.shape[1]):
            pairs = near_pairs(lo[:, j], hi[:, j], distance)
            if len(pairs):
                d = hull_distance_from_origin(S[pairs[:, 0], j] - S[pairs[:, 1], j])
                np.minimum.at(separation, pairs[:, 0], d)
                np.minimum.at(separation, pairs[:, 1], d)
    for i, entry in enumerate(robots):
        n = comp.n_bytes(i)
        entry.update({
            "bytes_compressed": n, "fits_compressed": n <= cflib_.MEMORY_BYTES,
            "compressed_certified": bool(on_grid and clearance[i] >= radius and separation[i] >= distance
                                         and within[i]),
            "compressed_clearance_lower_bound_m": float(clearance[i]) if on_grid else None,
            "compressed_separation_lower_bound_m": float(separation[i]) if on_grid else None,
            "compressed_within_limits": bool(within[i]) if on_grid else None,
            "compressed_error_m": float(error[i]),
        })
    return {
        "origin_m": [float(v) for v in comp.origin],
        "position_error_bound_m": comp.position_error_bound,
        "float32_deviation_m": float(deviation.max()),
        "error_margin_m": comp.position_error_bound + float(deviation.max()),
        "max_error_m": float(error.max()),
        "certificate": {
            "ok": cert.ok,
            "problems": cert.problems[:5],
            "separation_lower_bound_m": cert.separation_bound if on_grid else None,
            "clearance_lower_bound_m": float(clearance.min()) if on_grid else None,
            "limit_upper_bounds": {"v": cert.limit_bounds[0], "a": cert.limit_bounds[1], "j": cert.limit_bounds[2]},
        },
        "not_certified_robots": [r["robot"] for r in robots if not r["compressed_certified"]],
    }, comp
