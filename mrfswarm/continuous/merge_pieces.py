"""Pieces that span several discrete steps, still certified for all t.

Why. A Crazyflie holds its trajectory in 4096 bytes: 31 pieces of cflib's ``Poly4D``
(4 x 8 float32 and a duration, 132 bytes). One piece per MRF step does not fit a flight
of more than 31 steps, so ``smoothing.max_pieces`` (default 31, 0 = one piece per step)
has the continuous stage fly several steps with one polynomial piece where needed.

The proof still works step by step. A piece :math:`p` of degree D over
:math:`[t_j, t_{j+g}]`, restricted to step k's interval :math:`[t_k, t_{k+1}]`, is again a
polynomial of degree D in that step's normalized time; its tau-coefficients, and so its
Bernstein control points (of position and of each derivative, of each limit sub-interval),
are a *linear* map of the piece's (:func:`restriction_matrix`, de Casteljau's subdivision
at arbitrary points). Every robot's knots are step knots of the one time grid, so every
robot's flight splits into one polynomial per step, and on each step the proof of
:mod:`mrfswarm.continuous.regions` applies unchanged: position control points in the
step's region, relative control points of near pairs (both robots split at the same
times, so their differences are the relative curve's) in the half-plane, derivative
control points in the limit polygons. The certificate does exactly that: it splits the
pieces at the steps (:func:`step_pieces`) and checks the split pieces
(:func:`~mrfswarm.continuous.certificate.certify`). It would accept pieces merged
differently per robot as well; the planner merges the same steps for every robot, so the
flight keeps one (coarser) time grid.

How the planner makes them. Two adjacent step pieces whose derivatives 0..D agree at the
knot between them are one polynomial. The window problem shares derivatives 0..q-1 at
every knot already; a merged knot adds the rows "Taylor coefficients q..D of the left
piece at its end = those of the right piece at its start" (linear in the variables, with
coefficients from the symbolic piece: :mod:`mrfswarm.continuous.formulation`). Every
region, corridor and limit row of every step stays as it was: on the merged polynomial
they are exactly the rows on its subdivided control points. A solver meets the merge rows
only to its tolerance, so every solution is projected onto them
(:func:`project_blocks`: one polynomial per block, fitted to the step pieces with the
block's end states kept exactly) before it is checked and certified.

Which steps. Only where needed: window by window, the steps it flies are split into as
many pieces as keep the rest of the flight within budget (:func:`window_pieces`: the
share of pieces left per step left, never more steps than the window flies in one
piece). A window whose merged problem fails at every duration falls back to fewer steps
per piece and finally to one piece per step (whose witness keeps every window feasible);
the later windows then merge more. A flight that still needs more pieces (more than
``max_pieces`` windows) is reported, never hidden: ``result.json["piece_limit"]``.
"""

from __future__ import annotations

import numpy as np
from scipy.special import comb

from mrfswarm.trajectory.polynomial import PiecewisePolynomial, derivative_row, tau_to_time

#: Knots of a robot's trajectory and of the step grid agree to this (seconds).
KNOT_TOLERANCE = 1e-9


def block_sizes(steps: int, pieces: int) -> np.ndarray:
    """``steps`` consecutive steps cut into ``pieces`` blocks as even as possible (longer blocks first)."""
    pieces = max(1, min(int(pieces), int(steps)))
    base, extra = divmod(int(steps), pieces)
    return np.array([base + 1] * extra + [base] * (pieces - extra), dtype=int)


def window_pieces(window_steps: int, steps_left: int, pieces_left: int) -> int:
    """How many pieces a window that flies ``window_steps`` of the ``steps_left`` steps still to fly gets.

    All of them (one per step) while the rest fits one piece per step; otherwise the
    window's share of the pieces left, ``floor(window_steps * pieces_left / steps_left)``,
    at least one. Taking the share never raises the pieces needed per step left, so a
    flight whose windows all merge as asked ends within budget whenever its first window
    gets at least one piece by share.
    """
    if steps_left <= pieces_left:
        return window_steps
    return int(max(1, min(window_steps, (window_steps * max(pieces_left, 0)) // steps_left)))


def merged_knots(sizes: np.ndarray, steps: int) -> np.ndarray:
    """(steps - 1,) bool: knot j + 1 lies inside a block of ``sizes`` (blocks from the window's start; steps past them single)."""
    out = np.zeros(max(steps - 1, 0), dtype=bool)
    start = 0
    for g in sizes:
        out[start:start + g - 1] = True
        start += g
    return out


def restriction_matrix(degree: int, u0: float | np.ndarray, u1: float | np.ndarray) -> np.ndarray:
    r"""(..., D+1, D+1) ``R`` with ``R @ c`` the tau-coefficients of :math:`c(u_0 + (u_1 - u_0) s)` in s.

    The restriction of a piece (tau-coefficients ``c``) to the sub-interval
    :math:`[u_0, u_1]` of its normalized time; linear in ``c``:
    :math:`R_{kj} = \binom{j}{k} u_0^{j-k} (u_1 - u_0)^k` for :math:`j \ge k`. One matrix per
    element of ``u0``, ``u1`` (broadcast).
    """
    u0, h = np.asarray(u0, dtype=float)[..., None, None], (np.asarray(u1, dtype=float) - np.asarray(u0, dtype=float))[..., None, None]
    k = np.arange(degree + 1)
    C = comb(k[None, :], k[:, None])  # C[k, j] = binom(j, k), 0 for j < k
    upper = k[None, :] >= k[:, None]
    return np.where(upper, C * u0 ** np.where(upper, k[None, :] - k[:, None], 0) * h ** k[:, None], 0.0)


def _fractions(durations: np.ndarray) -> np.ndarray:
    """Where each step of a block starts and ends in the block's normalized time: (g + 1,), 0 to 1."""
    s = np.concatenate([[0.0], np.cumsum(durations)])
    return s / s[-1]


def block_polynomial(c: np.ndarray, durations: np.ndarray, derivative: int) -> np.ndarray:
    """One polynomial over a block of steps, from the steps' pieces.

    Parameters
    ----------
    c
        (g, D+1, ...) tau-coefficients of the g step pieces (each in its own normalized time).
    durations
        (g,) their durations.
    derivative
        q: derivatives 0..q-1 at the block's two ends are kept exactly.

    Returns
    -------
    numpy.ndarray
        (D+1, ...) tau-coefficients over the whole block: its ends' derivatives 0..q-1 are
        those of the first piece's start and the last piece's end; the other D + 1 - 2q
        degrees of freedom (none for D = 2q - 1: the ends determine the piece) are the
        least-squares fit of its restrictions to the step pieces' coefficients. Step pieces
        that are one polynomial (to rounding) give it back.
    """
    g, K = c.shape[0], c.shape[1]
    D, q = K - 1, derivative
    s = _fractions(np.asarray(durations, dtype=float))
    R = restriction_matrix(D, s[:-1], s[1:])  # (g, K, K)
    at0 = np.array([derivative_row(D, r, 0.0) for r in range(q)])
    at1 = np.array([derivative_row(D, r, 1.0) for r in range(q)])
    H = np.vstack([at0 @ R[0], at1 @ R[-1]])  # (2q, K)
    rest = c.reshape(g, K, -1)
    h = np.vstack([at0 @ rest[0], at1 @ rest[-1]])  # (2q, n)
    if 2 * q == K:
        return np.linalg.solve(H, h).reshape(c.shape[1:])
    P0 = np.linalg.lstsq(H, h, rcond=None)[0]
    _, _, Vt = np.linalg.svd(H)
    N = Vt[2 * q:].T  # (K, K - 2q): the null space of the end conditions
    A = R.reshape(g * K, K)  # the restrictions stacked
    b = rest.reshape(g * K, -1) - A @ P0
    w = np.linalg.lstsq(A @ N, b, rcond=None)[0]
    return (P0 + N @ w).reshape(c.shape[1:])


def restrict(P: np.ndarray, durations: np.ndarray) -> np.ndarray:
    """(g, D+1, ...) the step pieces' tau-coefficients of a block polynomial ``P`` (D+1, ...) over steps of ``durations``."""
    D = P.shape[0] - 1
    s = _fractions(np.asarray(durations, dtype=float))
    flat = P.reshape(D + 1, -1)
    return (restriction_matrix(D, s[:-1], s[1:]) @ flat).reshape((len(s) - 1,) + P.shape)


def project_blocks(Y: np.ndarray, B: np.ndarray, durations: np.ndarray, merged: np.ndarray, degree: int,
                   derivative: int) -> tuple[np.ndarray, np.ndarray]:
    """Knot derivatives and bubbles of a window solution whose merged blocks are exactly one polynomial each.

    Parameters
    ----------
    Y, B
        (G, M+1, q, dim) physical knot derivatives and (G, M, nb, dim) bubbles
        (:meth:`~mrfswarm.continuous.formulation.WindowFormulation.unpack`).
    durations
        (M,) step durations (seconds).
    merged
        (M - 1,) bool: knot j + 1 is inside a block (:func:`merged_knots`).

    Returns
    -------
    tuple of numpy.ndarray
        ``Y, B`` with each block's interior knots and bubbles those of the block's
        :func:`block_polynomial` (its ends, and every step outside a block, unchanged).
    """
    from mrfswarm.continuous.formulation import piece_maps

    merged = np.asarray(merged, dtype=bool)
    if not merged.any():
        return Y, B
    pm = piece_maps(degree, derivative)
    q = derivative
    T = np.asarray(durations, dtype=float)
    Y, B = np.array(Y, dtype=float), np.array(B, dtype=float)
    z = np.concatenate([Y[:, :-1], Y[:, 1:], B], axis=2)  # (G, M, nz, dim)
    c = np.einsum("ka,ma,gmad->mkgd", pm.E, T[:, None] ** pm.rpow[None, :], z)  # (M, K, G, dim)
    Einv = np.linalg.inv(pm.E)
    for a, b in _blocks(merged):
        P = block_polynomial(c[a:b], T[a:b], q)
        cs = restrict(P, T[a:b])  # (g, K, G, dim)
        zs = np.einsum("ak,mkgd->gmad", Einv, cs) / (T[a:b, None] ** pm.rpow[None, :])[None, :, :, None]
        Y[:, a + 1:b] = zs[:, 1:, :q]  # interior knots: the start of each piece after the first
        B[:, a:b] = zs[:, :, 2 * q:]
    return Y, B


def _blocks(merged: np.ndarray) -> list[tuple[int, int]]:
    """(first step, one past the last) of every block of two steps or more marked by ``merged``."""
    out, j, M = [], 0, len(merged) + 1
    while j < M:
        e = j
        while e < M - 1 and merged[e]:
            e += 1
        if e > j:
            out.append((j, e + 1))
        j = e + 1
    return out


def merge_trajectories(trajectories: list[PiecewisePolynomial], sizes: np.ndarray, derivative: int) -> list[PiecewisePolynomial]:
    """Trajectories of one piece per step merged into one piece per block of ``sizes`` steps (in order).

    Each block's piece is the :func:`block_polynomial` of its steps' pieces, which are
    one polynomial (to rounding) when the planner merged them.
    """
    sizes = np.asarray(sizes, dtype=int)
    if len(sizes) == trajectories[0].pieces:
        return trajectories
    edges = np.concatenate([[0], np.cumsum(sizes)])
    T = trajectories[0].durations
    c = np.stack([tr.tau_coefficients() for tr in trajectories], axis=2)  # (M, K, N, dim)
    pieces, Tb = [], []
    for a, b in zip(edges[:-1], edges[1:]):
        pieces.append(c[a] if b - a == 1 else block_polynomial(c[a:b], T[a:b], derivative))
        Tb.append(float(T[a:b].sum()))
    durations = np.array(Tb)
    coef = tau_to_time(np.stack(pieces).transpose(2, 0, 1, 3).reshape(-1, c.shape[1], c.shape[3]),
                       np.tile(durations, len(trajectories)))
    coef = coef.reshape(len(trajectories), len(durations), c.shape[1], c.shape[3])
    return [PiecewisePolynomial(durations, coef[i]) for i in range(len(trajectories))]


def step_split(piece_knots: np.ndarray, knot_times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Which piece flies each step, and where in the piece's normalized time the step starts and ends.

    Parameters
    ----------
    piece_knots
        (P + 1,) a trajectory's knots: each a step time of ``knot_times`` (to :data:`KNOT_TOLERANCE`),
        the first and last the grid's.
    knot_times
        (T + 1,) the step times.

    Returns
    -------
    tuple of numpy.ndarray or None
        ``piece`` (T,) int, ``u0``, ``u1`` (T,) in [0, 1] (exactly 0 and 1 at the piece's own
        knots); None when the knots are not step times as above.
    """
    piece_knots, knot_times = np.asarray(piece_knots, dtype=float), np.asarray(knot_times, dtype=float)
    steps, pieces = len(knot_times) - 1, len(piece_knots) - 1
    at = np.searchsorted(knot_times, piece_knots - KNOT_TOLERANCE)  # the step each knot is
    if (pieces > steps or at[0] != 0 or at[-1] != steps or np.any(np.diff(at) <= 0)
            or not np.allclose(knot_times[np.minimum(at, steps)], piece_knots, rtol=0, atol=KNOT_TOLERANCE)):
        return None
    durations = np.diff(piece_knots)
    piece = np.repeat(np.arange(pieces), np.diff(at))  # (steps,) the piece flying each step
    j = np.arange(steps)
    u0 = np.where(at[piece] == j, 0.0, (knot_times[:-1] - piece_knots[piece]) / durations[piece])
    u1 = np.where(at[piece + 1] == j + 1, 1.0, (knot_times[1:] - piece_knots[piece]) / durations[piece])
    return piece, u0, u1


def step_pieces(trajectories: list[PiecewisePolynomial], knot_times: np.ndarray) -> list[PiecewisePolynomial] | str:
    """Every trajectory split at the step times ``knot_times``: one piece per step, the same curves.

    Each piece spanning several steps is restricted to each of them (:func:`restriction_matrix`,
    linear in its coefficients); trajectories with one piece per step are returned as
    they are. Robots may be merged differently; their split pieces share the grid.

    Returns
    -------
    list of PiecewisePolynomial or str
        The split trajectories, or why they cannot be split: a robot whose knots are not
        step times (to :data:`KNOT_TOLERANCE`), or that does not start at the first and
        end at the last.
    """
    knot_times = np.asarray(knot_times, dtype=float)
    steps = len(knot_times) - 1
    dT = np.diff(knot_times)
    out: list[PiecewisePolynomial | None] = [None] * len(trajectories)
    groups: dict[bytes, list[int]] = {}
    for i, tr in enumerate(trajectories):
        if tr.pieces == steps:
            if not np.allclose(tr.knots, knot_times, rtol=0, atol=KNOT_TOLERANCE):
                return f"robot {i}'s pieces do not follow the common time grid"
            out[i] = tr
        else:
            groups.setdefault(tr.durations.tobytes(), []).append(i)
    for members in groups.values():
        tr = trajectories[members[0]]
        where = step_split(tr.knots, knot_times)
        if where is None:
            return f"robot {members[0]}'s pieces do not end on the common time grid's knots"
        piece, u0, u1 = where
        R = restriction_matrix(tr.degree, u0, u1)  # (steps, K, K)
        c = np.stack([trajectories[i].tau_coefficients() for i in members])  # (n, pieces, K, dim)
        split = np.einsum("jkl,njld->njkd", R, c[:, piece])
        for i, s in zip(members, split):
            out[i] = PiecewisePolynomial(dT, tau_to_time(s, dT))
    return [tr for tr in out if tr is not None]


def step_times(piece_knots: np.ndarray, knot_times: np.ndarray, piece_steps: np.ndarray) -> np.ndarray:
    """The step times of a flight whose pieces were retimed to ``piece_knots`` (P + 1,).

    The plan's piece p spans steps ``piece_steps[p]..piece_steps[p+1]`` over its knots
    ``knot_times[piece_steps]``; each step time inside it is moved with the piece's
    affine retiming (rounded knots of an export), so every robot's curve still splits at
    the same times and step k's region still holds where the plan put it.
    """
    knot_times, piece_steps = np.asarray(knot_times, dtype=float), np.asarray(piece_steps)
    old = knot_times[piece_steps]
    piece = np.clip(np.searchsorted(piece_steps, np.arange(len(knot_times)), side="right") - 1, 0, len(old) - 2)
    scale = np.diff(piece_knots) / np.diff(old)
    out = piece_knots[piece] + (knot_times - old[piece]) * scale[piece]
    out[piece_steps] = piece_knots  # the pieces' own knots exactly
    return out
