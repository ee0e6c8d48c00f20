"""A Crazyflie's trajectory memory, written with Bitcraze's ``cflib`` and read back.

The Crazyflie's high-level commander flies piecewise polynomials stored in a 4096-byte
trajectory memory, in one of two formats; both are packed here by ``cflib``'s own classes
(``cflib.crazyflie.mem``), through :class:`~cflib.crazyflie.mem.TrajectoryMemory`'s
``write_data`` with the radio replaced by a recorder, so the bytes are those ``cflib``
sends.

**Raw** (:class:`~cflib.crazyflie.mem.Poly4D`, what Crazyswarm2's ``upload_trajectory``
writes): per piece, the 8 power-basis coefficients (local time) of x, y, z and yaw and the
duration, all float32 (z: a 3-D trajectory's own polynomial, a 2-D one's constant altitude): 132 bytes a piece, so at most 31 pieces fit. The only change is the
rounding of every coefficient to float32; the firmware evaluates each piece by Horner's
rule in float32 (:func:`firmware_positions_raw` does the same).

**Compressed** (:class:`~cflib.crazyflie.mem.CompressedStart` then one
:class:`~cflib.crazyflie.mem.CompressedSegment` per piece, then a zero-duration segment
that ends the trajectory): a start point, then per piece its duration in whole
milliseconds and the Bezier control points 1..7 of each moving axis as int16 millimetres
(control point 0 is the previous piece's end; yaw stays at 0). A 2-D flight stores x and y,
z staying at the start's altitude: a piece takes 31 bytes (header 3, 2 x 7 x 2), the whole
11 + 31 M bytes, so 131 pieces fit. A 3-D flight stores z too: 45 bytes a piece, 90 fit.
int16 millimetres hold +/-32.767 m, so the points are written relative to a frame origin
(:func:`compress`: per axis, 0 when the flight fits around it, else the flight's centre;
the Crazyflie must then fly in a world frame whose origin is that point). Two roundings:

- every control point to a neighbouring millimetre: the nearest (at most 0.5 mm per axis)
  or, given the plan's regions and limits, one of its up to 2^d neighbours chosen so that
  the control points the certificate checks stay in their regions and the derivative ones
  within the limits (:func:`_round_inside`; at most 1 mm per axis). Since a Bezier piece is
  a convex combination of its control points (non-negative weights summing to one), every
  position of a piece moves by at most the largest control-point move, for all t;
- every knot time (not every duration: the error does not accumulate) to the nearest
  millisecond: a piece of duration T then takes T' = T + e with |e| <= 1 ms, its knots
  within 0.5 ms of the planned ones; a point at time t is the planned point of a time
  within 0.5 ms of t (the map from the new piece's time to the old is affine between
  knots that moved by at most 0.5 ms), so it is at most v_max x 0.5 ms away.

So the compressed flight is within the largest control-point move ``+ v_max x 0.5 ms`` of the
planned one at every instant (:attr:`Compressed.position_error_bound`; at most ``sqrt(d) mm + v_max
x 0.5 ms``, ``0.5 sqrt(d) mm + ...`` rounded to the nearest), in exact arithmetic. All robots
share the same rounded knots, so the pieces of a step still share their interval and the
continuous stage's certificate applies to the decoded flight as it stands
(:mod:`mrfswarm.export.crazyflie_memory` runs it). The firmware's own float32 arithmetic
(:func:`firmware_positions_compressed`: it rebuilds each piece's polynomial from the
control points and starts each piece at the float32 end of the previous one) adds some
micrometres, measured in the tests, not proven.

Decoding (:func:`decode_raw`, :func:`decode_compressed`) follows the firmware's documented
semantics (``pptraj.c``, ``pptraj_compressed.c``), since ``cflib`` writes but never reads
these formats.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from mrfswarm.continuous.merge_pieces import restriction_matrix, step_split
from mrfswarm.continuous.regions import Regions
from mrfswarm.errors import ExportError
from mrfswarm.trajectory.bernstein import control_point_matrix, control_points, monomial_to_bernstein
from mrfswarm.trajectory.polynomial import PiecewisePolynomial, tau_to_time
from mrfswarm.trajectory.uav_csv import to_rows

MEMORY_BYTES = 4096
"""The Crazyflie's trajectory memory."""
RAW_PIECE_BYTES = 132
COMPRESSED_START_BYTES = 8
COMPRESSED_PIECE_BYTES = 31  # header byte, uint16 duration, 7 x and 7 y int16 control points (a 2-D flight)
COMPRESSED_AXIS_BYTES = 14  # 7 int16 control points of one more axis (z of a 3-D flight)
COMPRESSED_END_BYTES = 3  # the zero-duration segment that ends a compressed trajectory
INT16_MAX = 32767
"""The largest int16: a coordinate of the compressed format is within +/-32.767 m of its origin."""
MAX_DURATION_MS = 65535
INSIDE_MM = 1e-6
"""In-region rounding counts a point closer than this to a region's edge (mm) as outside: the certificate
recomputes it in metres from other arithmetic (measured 1.6e-15 m)."""
INSIDE_LIMIT = 1e-9
"""The same for the limits, relative: a rounded derivative control point within this share of a limit counts as
over it (the certificate recomputes the norms from the decoded pieces; a corridor robot's rounded speed came
to 2.0000000000004934 against v_max 2, kept by a check without this margin and refused by the certificate)."""
WINDOW = 3
"""In-region rounding (:func:`_round_inside`) tries every floor/ceil choice of this many consecutive control
points on one axis at once (one point's millimetre can break a short piece's jerk limit alone)."""
DEGREE = 7
MODULES = ("cflib",)
INSTALL = "pip install 'mrfswarm[crazyflie]'"
_COUNTS = (0, 1, 3, 7)  # control points stored per axis for each storage type (constant, linear, cubic, degree 7)


def cflib_mem() -> Any:
    """``cflib.crazyflie.mem``, imported on use.

    Raises
    ------
    ExportError
        ``cflib`` is not installed (only :class:`ModuleNotFoundError` means that; any other
        import failure propagates).
    """
    try:
        from cflib.crazyflie import mem
    except ModuleNotFoundError as e:
        raise ExportError(f"the Crazyflie export needs cflib, which is not installed: {INSTALL}") from e
    return mem


def raw_pieces(trajectory: PiecewisePolynomial, altitude: float) -> list[Any]:
    """One ``cflib`` :class:`~cflib.crazyflie.mem.Poly4D` per piece: the rows of the uav_trajectories CSV.

    ``altitude`` is z of a planar trajectory (a 3-D one has its own). Degree above 7 or dimension above 4 is an
    :class:`~solvers.errors.InvalidProblem` (:func:`~mrfswarm.trajectory.uav_csv.to_rows`).
    """
    mem = cflib_mem()
    rows = to_rows(trajectory, altitude)
    return [mem.Poly4D(float(r[0]), *(mem.Poly4D.Poly([float(v) for v in r[1 + 8 * k:9 + 8 * k]])
                                      for k in range(4))) for r in rows]


class _Recorder:
    """Stands in for ``cflib``'s memory handler: keeps what :meth:`TrajectoryMemory.write_data` would send."""

    def __init__(self) -> None:
        self.data = b""

    def write(self, memory: Any, addr: int, data: bytes | bytearray, flush_queue: bool = False) -> bool:
        self.data = bytes(data)
        return True


def pack(elements: Sequence[Any]) -> bytes:
    """The bytes ``cflib``'s :class:`~cflib.crazyflie.mem.TrajectoryMemory` writes for ``elements``."""
    mem = cflib_mem()
    recorder = _Recorder()
    memory = mem.TrajectoryMemory(id=0, type=mem.MemoryElement.TYPE_TRAJ, size=MEMORY_BYTES, mem_handler=recorder)
    memory.trajectory = list(elements)
    n = memory.write_data(lambda *a: None)
    assert n == len(recorder.data)
    return recorder.data


def pack_raw(trajectory: PiecewisePolynomial, altitude: float) -> bytes:
    """The raw format's bytes of ``trajectory`` (:func:`raw_pieces` packed by ``cflib``)."""
    return pack(raw_pieces(trajectory, altitude))


def decode_raw(data: bytes, dim: int = 4) -> PiecewisePolynomial:
    """The pieces of raw-format ``data`` as stored (float32 values, held in float64): x, y, z, yaw.

    Keeps the first ``dim`` axes. Raises :class:`ExportError` if ``data`` is not whole pieces.
    """
    if len(data) % RAW_PIECE_BYTES or not data:
        raise ExportError(f"raw trajectory data must be whole {RAW_PIECE_BYTES}-byte pieces, got {len(data)} bytes")
    rows = np.frombuffer(data, dtype="<f4").reshape(-1, 33).astype(float)
    coefficients = rows[:, :32].reshape(-1, 4, DEGREE + 1)[:, :dim, :]
    return PiecewisePolynomial(rows[:, 32], np.moveaxis(coefficients, 1, 2))


def firmware_positions_raw(data: bytes, taus: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """x, y, z of raw-format ``data`` as the firmware computes them: float32 Horner per piece.

    Parameters
    ----------
    data
        Raw-format bytes.
    taus
        (S,) fractions of each piece, in [0, 1].

    Returns
    -------
    local_times : numpy.ndarray
        (M, S) float32 local times ``tau T_j`` (rounded to float32, as the firmware holds time).
    positions : numpy.ndarray
        (M, S, 3) float32.
    """
    rows = np.frombuffer(data, dtype="<f4").reshape(-1, 33)
    coefficients = rows[:, :24].reshape(-1, 3, DEGREE + 1)  # x, y, z
    s = (rows[:, 32:33].astype(float) * np.asarray(taus, dtype=float)[None, :]).astype(np.float32)
    x = np.zeros(s.shape + (3,), dtype=np.float32)
    for k in range(DEGREE, -1, -1):  # pptraj.c polyval: x = x * t + p[k], in float
        x = x * s[..., None] + coefficients[:, None, :, k]
    return s, x


# ---------------------------------------------------------------------------------------- compressed format


@dataclass(frozen=True)
class Compressed:
    """Every robot's flight in the compressed format's units, before ``cflib`` packs it.

    Attributes
    ----------
    origin
        (3,) the frame origin (metres, world frame): stored coordinates are relative to it.
    knots_ms
        Per robot, (M + 1,) knot times in whole milliseconds (each planned knot rounded).
    points_mm
        Per robot, (M, 8, d) int Bezier control points of x, y (and z of a 3-D flight),
        millimetres from the origin; point 0 of a piece is point 7 of the one before.
    z_mm
        A 2-D flight's altitude (int millimetres from the origin); None for a 3-D flight,
        whose z is in ``points_mm``.
    position_error_bound
        Proven bound (metres, exact arithmetic) on the distance between a compressed and
        the planned position at the same time (module docstring).
    """

    origin: np.ndarray
    knots_ms: list[np.ndarray]
    points_mm: list[np.ndarray]
    z_mm: int | None
    position_error_bound: float

    @property
    def dim(self) -> int:
        """The stored axes: 2 (x, y at the altitude ``z_mm``) or 3."""
        return int(self.points_mm[0].shape[-1])

    @property
    def piece_bytes(self) -> int:
        """Bytes of one piece: 31 for a 2-D flight, 45 for a 3-D one."""
        return COMPRESSED_PIECE_BYTES + COMPRESSED_AXIS_BYTES * (self.dim - 2)

    def n_bytes(self, robot: int) -> int:
        """Bytes of robot ``robot``'s compressed trajectory (start, pieces, end)."""
        return COMPRESSED_START_BYTES + self.piece_bytes * len(self.points_mm[robot]) + COMPRESSED_END_BYTES

    def start_mm(self, robot: int) -> list[int]:
        """Robot ``robot``'s start x, y, z in millimetres from the origin."""
        p = [int(v) for v in self.points_mm[robot][0, 0]]
        return p if self.z_mm is None else p + [self.z_mm]


def compress(trajectories: Sequence[PiecewisePolynomial], altitude: float, v_max: float,
             regions: Regions | None = None, knot_times: np.ndarray | None = None,
             limits: tuple[float, float, float] | None = None) -> Compressed:
    """Round every robot's flight to the compressed format (module docstring).

    Parameters
    ----------
    trajectories
        Trajectories of degree <= 7 (the planner's), one per robot, all 2-D or all 3-D.
    altitude
        z of a 2-D flight (metres; a 3-D flight has its own).
    v_max
        An upper bound on every robot's speed (the plan's exact maximum): the timing part
        of :attr:`Compressed.position_error_bound`.
    regions
        The plan's safe regions (one per robot and step): each control point is then
        rounded to one of its (up to 4) neighbouring millimetre points such that the
        control points the certificate checks stay in their steps' regions
        (:func:`_round_inside`), nearest first; a point moves at most 1 mm per axis
        instead of 0.5. Their slabs have as many axes as the trajectories. Without them, or when the robots' pieces differ in their knots,
        to the nearest.
    knot_times
        (T + 1,) the plan's step times, where pieces span several steps
        (:mod:`mrfswarm.continuous.merge_pieces`): each piece's knots are step times, and
        its part in step k must lie in region k. Default: one piece per step.
    limits
        (v_max, a_max, j_max): with ``regions``, the rounding also keeps the certificate's
        derivative control points within them where it can (a millimetre matters on short
        pieces: :func:`_round_inside`).

    Raises
    ------
    ExportError
        A flight that spans more than the format holds around one origin (names the span),
        a piece shorter than 0.5 ms or longer than 65.535 s, a degree above 7.
    """
    trs = [tr.with_degree(DEGREE) if tr.degree < DEGREE else tr for tr in trajectories]
    dim = trs[0].dim
    for i, tr in enumerate(trs):
        if tr.degree > DEGREE or tr.dim not in (2, 3) or tr.dim != dim:
            raise ExportError(f"robot {i}: the compressed format holds pieces of degree <= {DEGREE} in 2 or 3 "
                              f"dimensions, the same for every robot; got degree {tr.degree} in dimension {tr.dim} "
                              f"(robot 0: {dim})")
    cps = [control_points(tr) for tr in trs]  # (M, 8, d) each
    flat = np.concatenate([p.reshape(-1, dim) for p in cps])
    lo, hi = flat.min(axis=0), flat.max(axis=0)
    if dim == 2:
        lo, hi = np.append(lo, altitude), np.append(hi, altitude)
    reach = INT16_MAX / 1000.0
    origin = np.zeros(3)
    if np.any(np.maximum(-lo, hi) > reach):  # shift the frame: whole metres if that fits, else the centre
        origin = np.where(np.maximum(-lo, hi) > reach, np.round((lo + hi) / 2), 0.0)
        if np.any(np.maximum(origin - lo, hi - origin) > reach):
            origin = np.where(np.maximum(-lo, hi) > reach, np.round((lo + hi) / 2 * 1000) / 1000, 0.0)
    if np.any(np.maximum(origin - lo, hi - origin) > reach + 4e-4):
        span = hi - lo
        raise ExportError(f"the flight spans {span[0]:.3f} m x {span[1]:.3f} m (z up to {hi[2]:.3f} m); the "
                          f"compressed Crazyflie format holds +/-{reach} m around one origin ({2 * reach:.3f} m)")
    knots = []
    for i, tr in enumerate(trs):
        k = np.rint(tr.knots * 1000).astype(np.int64)
        d = np.diff(k)
        if d.min() < 1 or d.max() > MAX_DURATION_MS:
            j = int(np.argmin(d)) if d.min() < 1 else int(np.argmax(d))
            raise ExportError(f"robot {i}'s piece {j} lasts {tr.durations[j]:.6g} s; the compressed format holds "
                              f"1 ms to {MAX_DURATION_MS / 1000} s a piece")
        knots.append(k)
    split = None
    if regions is not None and len(cps) == regions.robots and all(np.array_equal(tr.knots, trs[0].knots) for tr in trs):
        steps = trs[0].knots if knot_times is None else knot_times
        split = step_split(trs[0].knots, steps) if len(steps) == regions.steps + 1 else None
    if regions is not None and split is not None:
        points = list(_round_inside(np.stack(cps), origin[:dim], regions, split, np.diff(knots[0]), limits))
    else:
        points = [np.rint((p - origin[:dim]) * 1000).astype(np.int64) for p in cps]
    moved = max(float(np.linalg.norm(n / 1000 + origin[:dim] - p, axis=-1).max()) for n, p in zip(points, cps))
    z_mm = int(np.rint((altitude - origin[2]) * 1000)) if dim == 2 else None
    bound = moved + float(v_max) * 0.5e-3
    return Compressed(origin, knots, points, z_mm, float(bound))


def _round_inside(P: np.ndarray, origin: np.ndarray, regions: Regions, split: tuple[np.ndarray, np.ndarray, np.ndarray],
                  durations: np.ndarray | None = None, limits: tuple[float, float, float] | None = None,
                  sweeps: int = 8) -> np.ndarray:
    """Control points (N, M, 8, d) in int mm from ``origin`` (d,), each at a neighbouring mm point, such that
    what the certificate checks still holds where such points can be found.

    Step k is flown by piece ``piece[k]`` over ``[u0[k], u1[k]]`` of its normalized time
    (``split``, :func:`~mrfswarm.continuous.merge_pieces.step_split`); its control points,
    those the certificate checks, are fixed convex combinations of the piece's (de
    Casteljau's subdivision: :func:`~mrfswarm.continuous.merge_pieces.restriction_matrix` in
    the Bernstein basis; the identity for a piece of one step), as are, divided by the
    step's duration to the r-th power, those of its derivatives. The end points are
    shared (point 7 of piece j is point 0 of piece j + 1), so a robot's points are one
    chain, piece j its points 7j..7j+7.

    Each point takes one of its 2^d floor/ceil combinations: first the nearest; then, for
    the pieces that fail a check, coordinate descent over a few sweeps: every choice of
    :data:`WINDOW` consecutive points of the chain on one axis (across knots too), for
    every robot and window two pieces apart whose pieces fail at once (the others keep
    their points), keeping the one under which the (one or two) pieces these points
    shape fail the fewest checks (then by the least excess, then the nearest); only
    those pieces' steps are evaluated (17 x faster on 50 robots, 2.0 -> 0.12 s). The
    checks: the steps' control points in their regions (excess in millimetres) and,
    given the rounded piece ``durations`` (M, ms) and ``limits``,
    their speed, acceleration and jerk control points on the certificate's
    :data:`~mrfswarm.continuous.formulation.LIMIT_PARTS` sub-intervals within the limits
    (excess relative to the limit). A millimetre at one point moves a jerk control point
    by 210 mm / T^3, 1.4 m/s^3 on a 0.53 s piece: short steps need the windows. Whether
    the result is safe is for the certificate to say (:mod:`mrfswarm.export.crazyflie_memory`
    runs it on the decoded flight, with the separation of pairs this does not look at).
    """
    from mrfswarm.continuous.formulation import LIMIT_PARTS

    piece, u0, u1 = split
    N, M, K, d = P.shape
    D = K - 1
    chain_mm = (np.concatenate([P[:, :, :D].reshape(N, M * D, d), P[:, -1:, D]], axis=1) - origin) * 1000  # (N, C, d)
    C = chain_mm.shape[1]
    floor = np.floor(chain_mm)
    frac = chain_mm - floor  # a point's bit b on an axis puts it at floor + b, |frac - b| mm away
    at = D * np.arange(M)[:, None] + np.arange(K)[None, :]  # (M, K): piece j's points in the chain
    Bm = monomial_to_bernstein(D)
    to_tau = restriction_matrix(D, u0, u1) @ np.linalg.inv(Bm)  # (S, K, K): the step's tau-coefficients
    W = Bm @ to_tau  # (S, K, K): the step's control points from the piece's
    W[(u0 == 0) & (u1 == 1)] = np.eye(K)  # a step that is its own piece: its points exactly
    derivative = []
    if durations is not None and limits is not None:
        h = (u1 - u0) * np.asarray(durations, dtype=float)[piece] / 1000.0  # (S,) the step's duration, ms -> s
        for r, lim in zip((1, 2, 3), limits):
            derivative.append(control_point_matrix(D, r, LIMIT_PARTS) @ to_tau / (h[:, None, None] ** r * lim * 1000.0))
    ax = regions.axes.transpose(1, 0, 2, 3)  # (N, S, d slabs, d)
    shift = np.einsum("nsad,d->nsa", ax, origin * 1000)  # the slabs in mm from the origin
    lower = regions.lower.transpose(1, 0, 2) * 1000 - shift
    upper = regions.upper.transpose(1, 0, 2) * 1000 - shift
    # each piece's steps, padded to the most a piece flies (a merged piece flies several)
    per = np.bincount(piece, minlength=M)
    own = np.arange(max(int(per.max(initial=1)), 1))
    own_valid = own[None, :] < per[:, None]  # (M, most)
    own_step = np.where(own_valid, np.concatenate([[0], np.cumsum(per)[:-1]])[:, None] + own[None, :], 0)

    def piece_failing(flying: np.ndarray, robots: np.ndarray, pieces: np.ndarray) -> np.ndarray:
        """(n,): per piece ``pieces`` of ``robots`` flown with the control points ``flying`` (n, K, d),
        how many of its steps' checks fail, plus (below 1) by how much."""
        st, ok = own_step[pieces], own_valid[pieces]  # (n, most)
        f = flying[:, None]  # (n, 1, K, d)
        s = (W[st] @ f) @ ax[robots[:, None], st].swapaxes(-1, -2)  # (n, most, K, slabs)
        lo, up = lower[robots[:, None], st][:, :, None], upper[robots[:, None], st][:, :, None]
        excess = [np.maximum(np.maximum(lo - s, s - up) + INSIDE_MM, 0.0).reshape(len(st), st.shape[1], -1)]
        for L in derivative:
            excess.append(np.maximum(np.linalg.norm(L[st] @ f, axis=-1) - (1.0 - INSIDE_LIMIT), 0.0))
        e = np.concatenate(excess, axis=-1) * ok[:, :, None]
        total = e.sum(axis=(1, 2))
        return (e > 0).sum(axis=(1, 2)) + total / (1.0 + total)

    def failing(bits: np.ndarray) -> np.ndarray:
        """(N, M): :func:`piece_failing` of every piece of every robot."""
        flying = (floor + bits)[:, at].reshape(N * M, K, d)
        return piece_failing(flying, np.repeat(np.arange(N), M), np.tile(np.arange(M), N)).reshape(N, M)

    bits = (frac > 0.5).astype(float)  # (N, C, d): the nearest first
    w = min(WINDOW, C)
    combos = ((np.arange(2 ** w)[:, None] >> np.arange(w)[None, :]) & 1).astype(float)  # (2^w, w)
    O = len(combos)
    stride = 2 * D  # windows this far apart shape no piece in common (a window spans at most one knot)
    for _ in range(sweeps):
        score = failing(bits)  # (N, M), kept current below as windows change
        if not score.any():
            break
        changed = False
        for offset in range(min(stride, C - w + 1)):
            starts = np.arange(offset, C - w + 1, stride)
            window = starts[:, None] + np.arange(w)[None, :]  # (n_w, w) chain points
            # the pieces each window shapes, those holding one of its points: one, or two across a knot
            first = np.maximum((window[:, 0] - 1) // D, 0)
            last = np.minimum(window[:, -1] // D, M - 1)
            two = last != first
            for axis in range(d):
                # only windows whose pieces fail: elsewhere the points stay as they are
                rob, win = np.nonzero(score[:, first] + np.where(two, score[:, last], 0.0) > 0)
                if len(rob) == 0:
                    continue
                pairs = np.arange(len(rob))
                across = np.flatnonzero(two[win])  # the pairs whose window shapes a second piece
                parts = []  # (pairs, O) scores of their first piece, (across, O) of their second
                for sel, pc in ((pairs, first[win]), (across, last[win][across])):
                    if len(sel) == 0:
                        parts.append(np.zeros((0, O)))
                        continue
                    who = rob[sel]
                    flying = np.repeat(bits[who[:, None], at[pc]][:, None], O, axis=1)  # (n, O, K, d)
                    pos = window[win[sel]] - D * pc[:, None]  # (n, w) the window's points in the piece
                    for t in range(w):
                        inside = np.flatnonzero((pos[:, t] >= 0) & (pos[:, t] < K))
                        flying[inside, :, pos[inside, t], axis] = combos[:, t]
                    flying += floor[who[:, None], at[pc]][:, None]
                    parts.append(piece_failing(flying.reshape(-1, K, d), np.repeat(who, O),
                                               np.repeat(pc, O)).reshape(len(sel), O))
                one, other = parts
                scores = one.copy()  # (n, O)
                scores[across] += other
                near = np.abs(frac[rob[:, None], window[win], axis][:, None, :] - combos[None]).sum(axis=-1)
                low = scores.min(axis=1, keepdims=True)
                pick = np.argmin(np.where(scores <= low + 1e-12, near, np.inf), axis=1)  # (n,)
                new = combos[pick]  # (n, w)
                if np.any(new != bits[rob[:, None], window[win], axis]):
                    changed = True
                    bits[rob[:, None], window[win], axis] = new
                score[rob, first[win]] = one[pairs, pick]
                score[rob[across], last[win][across]] = other[np.arange(len(across)), pick[across]]
        if not changed:
            break
    chain = (floor + bits).astype(np.int64)
    return chain[:, at]


def _metres(n: int) -> float:
    """A float that ``cflib``'s encoders (``int(value * 1000)``, truncating) turn into exactly ``n``."""
    return (n + (0.5 if n > 0 else -0.5 if n < 0 else 0.0)) / 1000.0


def compressed_elements(c: Compressed, robot: int) -> list[Any]:
    """Robot ``robot``'s ``cflib`` elements: a CompressedStart, a CompressedSegment per piece, the end segment."""
    mem = cflib_mem()
    p, k = c.points_mm[robot], c.knots_ms[robot]
    out = [mem.CompressedStart(*(_metres(v) for v in c.start_mm(robot)), 0.0)]
    for j, d in enumerate(np.diff(k)):
        axes = [[_metres(int(v)) for v in p[j, 1:, a]] for a in range(c.dim)] + [[]] * (3 - c.dim)
        out.append(mem.CompressedSegment(_metres(int(d)), *axes, []))
    out.append(mem.CompressedSegment(0.0, [], [], [], []))
    return out


def pack_compressed(c: Compressed, robot: int) -> bytes:
    """Robot ``robot``'s compressed bytes, packed by ``cflib``; checked to decode to exactly the rounded values."""
    data = pack(compressed_elements(c, robot))
    start, segments = parse_compressed(data)
    ok = (start[:3] == c.start_mm(robot) and len(segments) == len(c.points_mm[robot])
          and all(ms == d and np.array_equal(np.array(pts[:c.dim]).T, c.points_mm[robot][j, 1:])
                  and not any(pts[c.dim:])
                  for j, ((ms, pts), d) in enumerate(zip(segments, np.diff(c.knots_ms[robot])))))
    if not ok:  # cflib's encoders changed: never upload what was not meant
        raise ExportError(f"robot {robot}: cflib's compressed packing does not hold the rounded control points")
    return data


def parse_compressed(data: bytes) -> tuple[list[int], list[tuple[int, list[list[int]]]]]:
    """Compressed-format bytes as stored: the start (x, y, z mm, yaw in 1/10 degree) and, per
    segment before the ending one, ``(duration_ms, [x points, y points, z points, yaw points])``.

    Raises :class:`ExportError` on truncated data or a missing end segment.
    """
    if len(data) < COMPRESSED_START_BYTES:
        raise ExportError(f"compressed trajectory data too short: {len(data)} bytes")
    start = list(struct.unpack_from("<4h", data, 0))
    at = COMPRESSED_START_BYTES
    segments: list[tuple[int, list[list[int]]]] = []
    while True:
        if at + 3 > len(data):
            raise ExportError("compressed trajectory data ends without its zero-duration end segment")
        types, ms = struct.unpack_from("<BH", data, at)
        at += 3
        if ms == 0:
            return start, segments
        counts = [_COUNTS[(types >> (2 * a)) & 3] for a in range(4)]
        if at + 2 * sum(counts) > len(data):
            raise ExportError("compressed trajectory data ends inside a segment, without its zero-duration end segment")
        values = list(struct.unpack_from(f"<{sum(counts)}h", data, at))
        at += 2 * sum(counts)
        axes, i = [], 0
        for n in counts:
            axes.append(values[i:i + n])
            i += n
        segments.append((ms, axes))


def decode_compressed(data: bytes, origin: np.ndarray, dim: int = 3) -> PiecewisePolynomial:
    """The trajectory compressed-format ``data`` stands for, in exact arithmetic, in the world frame.

    Each piece is the Bezier curve of the previous end and its stored points (a constant
    axis keeps the previous end, a linear one goes straight to its point, a cubic or
    degree-7 one has those control points), over its stored duration; ``origin`` (3,) is
    added back. Keeps the first ``dim`` of x, y, z.
    """
    start, segments = parse_compressed(data)
    if not segments:
        raise ExportError("compressed trajectory data holds no piece")
    end = np.array(start[:3], dtype=float) / 1000.0
    B_inv = np.linalg.inv(monomial_to_bernstein(DEGREE))
    durations, coefficients = [], []
    for ms, axes in segments:
        P = np.empty((DEGREE + 1, 3))
        for a in range(3):
            pts = np.array([end[a], *(np.array(axes[a], dtype=float) / 1000.0)])
            P[:, a] = _elevate(pts)
        T = ms / 1000.0
        durations.append(T)
        coefficients.append(tau_to_time((B_inv @ P)[None], np.array([T]))[0])
        end = P[-1]
    c = np.array(coefficients)
    c[:, 0, :] += np.asarray(origin, dtype=float)
    return PiecewisePolynomial(np.array(durations), c[:, :, :dim])


def _elevate(points: np.ndarray) -> np.ndarray:
    """Bezier control points of degree len-1 (0, 1, 3 or 7) as the 8 of the same curve in degree 7."""
    n = len(points) - 1
    if n == DEGREE:
        return points
    if n == 0:
        return np.full(DEGREE + 1, points[0])
    out = points
    for m in range(n, DEGREE):  # degree elevation: Q_i = i/(m+1) P_{i-1} + (1 - i/(m+1)) P_i
        i = np.arange(m + 2)
        a = i / (m + 1)
        padded = np.concatenate([[0.0], out, [0.0]])
        out = a * padded[:-1] + (1 - a) * padded[1:]
    return out


def firmware_positions_compressed(data: Sequence[bytes], taus: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """x, y, z of compressed-format trajectories as the firmware computes them, in float32.

    As ``pptraj_compressed.c`` and ``pptraj.c`` do: each piece's polynomial is rebuilt
    from its control points (``polybezier``, then ``polystretchtime``), its first control
    point being the float32 value of the previous piece at its end (``poly4d_eval``), and
    evaluated by Horner's rule, all in float32; positions relative to the frame origin.
    Robots are taken together, so their data must have the same segment layout.

    Parameters
    ----------
    data
        N robots' compressed bytes.
    taus
        (S,) fractions of each piece, in [0, 1].

    Returns
    -------
    durations : numpy.ndarray
        (N, M) float32 piece durations.
    positions : numpy.ndarray
        (N, M, S, 3) float32, at the local times ``float32(tau * duration)``.
    """
    f = np.float32
    parsed = [parse_compressed(d) for d in data]
    N, M = len(parsed), len(parsed[0][1])
    if any(len(s) != M for _, s in parsed):
        raise ExportError("robots' compressed trajectories differ in piece count; evaluate them one by one")
    facs = [1, 1, 2, 6, 24, 120, 720, 5040]
    taus = np.asarray(taus, dtype=float)
    prev = np.array([[v / f(1000.0) for v in (f(s[0]), f(s[1]), f(s[2]))] for s, _ in parsed], dtype=f)  # (N, 3)
    durations = np.empty((N, M), dtype=f)
    out = np.empty((N, M, len(taus), 3), dtype=f)
    for j in range(M):
        T = np.array([f(seg[j][0] / 1000.0) for _, seg in parsed], dtype=f)  # ms / 1000.0 in double, stored as float
        durations[:, j] = T
        p = np.zeros((N, 3, DEGREE + 1), dtype=f)
        for a in range(3):
            stored = np.array([seg[j][1][a] for _, seg in parsed], dtype=f) / f(1000.0)  # (N, n - 1)
            x = np.concatenate([prev[:, a:a + 1], stored.reshape(N, -1)], axis=1)
            n = x.shape[1]
            if n == 1:
                p[:, a, 0] = x[:, 0]
            elif n == 2:  # polylinear
                p[:, a, 0] = x[:, 0]
                p[:, a, 1] = (x[:, 1] - x[:, 0]) / T
            else:  # polybezier, then polystretchtime
                deg = n - 1
                for jj in range(deg + 1):
                    coeff = np.zeros(N, dtype=f)
                    sign = -1 if jj % 2 else 1
                    for i in range(jj + 1):
                        coeff = coeff + f(sign) * x[:, i] / f(facs[i]) / f(facs[jj - i])
                        sign = -sign
                    p[:, a, jj] = coeff * f(facs[deg]) / f(facs[deg - jj])
                recip = f(1.0) / T
                scale = recip.copy()
                for i in range(1, DEGREE + 1):
                    p[:, a, i] = p[:, a, i] * scale
                    scale = scale * recip
        s = (T[:, None].astype(float) * taus[None, :]).astype(f)  # (N, S)
        x_ = np.zeros((N, len(taus), 3), dtype=f)
        e = np.zeros((N, 3), dtype=f)
        for k in range(DEGREE, -1, -1):
            x_ = x_ * s[:, :, None] + p[:, None, :, k]
            e = e * T[:, None] + p[:, :, k]
        out[:, j] = x_
        prev = e  # the next piece starts where this one ends, in float32
    return durations, out
