"""One MRF step's energy, in the pairwise form every optimizer of :mod:`solvers.mrf` takes.

For the interaction graph G_t and label sets X^t, the swarm energy of a labelling x is

    eps(x) = sum_c E_c(x_c) = sum_i w_i rho_S(x_i) + sum_{(i,j) in G_t} w_ij rho_I(|x_i - x_j|)

(pairwise reduction, :mod:`mrfswarm.discrete.interaction_graph`). Hard conflicts are the robot
pairs, neighbours in G_t or not, whose straight moves would bring them closer than one
cell in the downwash-scaled metric (:mod:`mrfswarm.discrete.motion`); the interaction
rho_I uses the plain Euclidean distance (downwash is a safety rule, not a preference of
the swarm's shape).

Cells are (N, d), d = 2 or 3: the tables below are indexed by offsets of d axes, by the
same lines in the plane and in space.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from mrfswarm.discrete.interaction_graph import CliqueWeights
from mrfswarm.discrete.label_sets import LabelSets
from mrfswarm.discrete.motion import (
    MIN_SEPARATION,
    cell_values,
    interaction_radius,
    min_distance_during_move,
    nearby_pairs,
    scaled,
    stencil,
)
from mrfswarm.discrete.potentials import Morse
from mrfswarm.errors import ConfigError
from mrfswarm.geometry import downwash_scale
from solvers.mrf import PairwiseMRF


def _offset_radii(order: int, ndim: int, downwash: float) -> np.ndarray:
    """(d,) per-axis radius of the integer start offsets that can collide within a step.

    Pairs farther than :func:`interaction_radius` apart in the scaled metric cannot, so
    an offset needs |d_k| * scale_k <= that radius on every axis k.
    """
    return np.floor(interaction_radius(order) / downwash_scale(ndim, downwash)).astype(np.intp)


def _offset_index(d0: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """Flat index of integer offsets (..., d) in the box |d_k| <= radii[k] (row-major)."""
    return np.ravel_multi_index(tuple(np.moveaxis(d0 + radii, -1, 0)), tuple(2 * radii + 1))


#: Offset-move pairs whose distances :func:`collision_table` computes at once (a few MB of temporaries each).
_CHUNK = 1 << 18
#: Most entries (bytes) of a :func:`collision_table`: 2 ** 30 holds order 20 on voxels, 16 at downwash 3.
MAX_TABLE = 1 << 30


def check_order(order: int, ndim: int, downwash: float) -> None:
    """Refuse a search order whose collision table would not fit in :data:`MAX_TABLE` bytes.

    mrf.order's range (1..32) suits a 2-D map; on voxels the table grows with the cube of the
    stencil and with the downwash: order 32 on voxels needs 8.8 GB, 26 GB at downwash 3.

    Raises
    ------
    ConfigError
        Naming mrf.order and the largest order that fits.
    """
    def size(n: int) -> int:
        return int(np.prod(2 * _offset_radii(n, ndim, downwash) + 1)) * len(stencil(n, ndim)) ** 2

    if size(order) <= MAX_TABLE:
        return
    fits = max((n for n in range(1, order) if size(n) <= MAX_TABLE), default=1)
    where = "a 3-D map" if ndim == 3 else "a 2-D map"
    raise ConfigError(f"mrf.order = {order}: on {where} at scenario.downwash = {downwash:g} a step's collision table "
                      f"would take {size(order) / 1e9:.1f} GB; give at most {fits}")


@lru_cache(maxsize=16)
def collision_table(order: int, ndim: int = 2, downwash: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Which pairs of stencil moves collide, for every integer start offset in range.

    Returns
    -------
    table
        (G, S, S) bool: ``table[g, a, b]`` is True when robots whose start cells differ by
        the g-th offset d0 (robot i minus robot j) and that make moves a and b come closer
        than one cell during the step, in the downwash-scaled metric.
    R
        (d,) offsets d0 with |d_k| <= R[k] are tabulated, in row-major order:
        g = :func:`_offset_index` (d0, R) (in 2-D, (dx + R) (2R + 1) + (dy + R)).
    """
    check_order(order, ndim, downwash)
    off = stencil(order, ndim)
    S = len(off)
    R = _offset_radii(order, ndim, downwash)
    axes = np.meshgrid(*(np.arange(-r, r + 1) for r in R), indexing="ij")
    d0 = np.stack([x.ravel() for x in axes], axis=1).astype(float)  # (G, d)
    # the distance depends on the relative move a - b only: each distinct one once (S² pairs, far fewer moves),
    # in chunks of offsets (all at once, order 16 on voxels took 24 GB of temporaries)
    v, pair = np.unique((off[:, None, :] - off[None, :, :]).reshape(-1, ndim), axis=0, return_inverse=True)
    pair = pair.reshape(S, S)
    v = scaled(v, downwash)[None]
    table = np.empty((len(d0), S, S), dtype=bool)
    chunk = max(1, _CHUNK // len(v[0]))
    for a in range(0, len(d0), chunk):
        dist = min_distance_during_move(scaled(d0[a:a + chunk], downwash)[:, None, :], v)
        table[a:a + chunk] = (dist < MIN_SEPARATION - 1e-9)[:, pair]
    table[(d0 ** 2).sum(axis=1) == 0] = False  # two robots never share a start cell
    table.setflags(write=False)
    R.setflags(write=False)
    return table, R


@lru_cache(maxsize=16)
def _collision_rows(order: int, ndim: int = 2, downwash: float = 1.0) -> np.ndarray:
    """(G, S) uint64: bit b of row (g, a) is ``collision_table(order, ndim, downwash)[0][g, a, b]`` (S <= 64)."""
    table, _ = collision_table(order, ndim, downwash)
    weights = np.uint64(1) << np.arange(table.shape[2], dtype=np.uint64)
    rows = (table.astype(np.uint64) * weights).sum(axis=2, dtype=np.uint64)
    rows.setflags(write=False)
    return rows


def _move_masks(labels: LabelSets) -> np.ndarray:
    """(N,) uint64: bit s set when stencil move s is one of the robot's valid labels."""
    bits = np.uint64(1) << labels.index.astype(np.uint64)
    return np.where(labels.valid, bits, np.uint64(0)).sum(axis=1, dtype=np.uint64)


def conflict_tables(labels: LabelSets, downwash: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Pairs of robots and the label pairs that would collide within the step.

    Every pair of robots that could come closer than one cell (downwash-scaled metric,
    ``downwash`` = c) is checked, graph neighbours or not.

    Returns
    -------
    pairs
        (C, 2) robot pairs with at least one forbidden label pair.
    mask
        (C, L, L) True where the pair's moves come closer than one cell; False on
        padding labels.
    """
    ndim = labels.ndim
    table, R = collision_table(labels.order, ndim, downwash)
    starts = labels.starts
    L = labels.index.shape[1]
    pairs = nearby_pairs(scaled(starts, downwash), interaction_radius(labels.order))
    if len(pairs) == 0:
        return pairs, np.zeros((0, L, L), dtype=bool)
    d0 = starts[pairs[:, 0]] - starts[pairs[:, 1]]
    g = _offset_index(d0, R)
    possible = np.asarray(table.reshape(len(table), -1).any(axis=1))[g]
    pairs, g = pairs[possible], g[possible]
    if len(pairs) and table.shape[1] <= 64:
        # Before the (C, L, L) tables, keep the pairs with a colliding pair of *their* moves:
        # with each robot's moves as a bitmask over the stencil and each offset's collisions
        # as one bitmask row per move, S word operations per pair. In a dense swarm most
        # nearby pairs have none (their label sets are disjoint and short).
        rows = _collision_rows(labels.order, ndim, downwash)
        moves = _move_masks(labels)
        mi, mj = moves[pairs[:, 0]], moves[pairs[:, 1]]
        hit = np.zeros(len(pairs), dtype=bool)
        for a in range(table.shape[1]):
            has = (mi >> np.uint64(a)) & np.uint64(1) != 0
            hit |= has & (rows[g, a] & mj != 0)
        pairs, g = pairs[hit], g[hit]
    if len(pairs) == 0:
        return pairs, np.zeros((0, L, L), dtype=bool)
    S = table.shape[1]
    ia = labels.index[pairs[:, 0]]  # (C, L)
    ib = labels.index[pairs[:, 1]]
    row = (g * S)[:, None] + ia  # (C, L): flat row (g, a) of the table
    mask = table.reshape(-1, S).take(row, axis=0)  # (C, L, S)
    mask = np.take_along_axis(mask, np.broadcast_to(ib[:, None, :], mask.shape[:2] + ib.shape[1:]), axis=2)
    valid = labels.valid
    mask &= valid[pairs[:, 0]][:, :, None] & valid[pairs[:, 1]][:, None, :]
    keep = mask.reshape(len(pairs), -1).any(axis=1)
    return pairs[keep], mask[keep]


class _MorseBySquaredDistance:
    """rho_I tabulated over integer squared cell distances, grown on demand."""

    def __init__(self, morse: Morse, resolution: float) -> None:
        self.morse, self.resolution = morse, resolution
        self.table = np.zeros(0)

    def __call__(self, d2: np.ndarray) -> np.ndarray:
        need = int(d2.max(initial=0)) + 1
        if need > len(self.table):
            size = max(need, 2 * len(self.table), 1024)
            self.table = np.asarray(self.morse(np.sqrt(np.arange(size, dtype=float)) * self.resolution))
        return self.table[d2]


@lru_cache(maxsize=8)
def _morse_table(morse: Morse, resolution: float) -> _MorseBySquaredDistance:
    return _MorseBySquaredDistance(morse, resolution)


#: Start offsets (|dx|, |dy| <= this many cells) whose pairwise tables are gathered from
#: :func:`_morse_box`; longer edges compute their distances directly.
_OFFSET_RADIUS = 32
#: Edges per chunk when gathering pairwise tables.
_CHUNK = 256


@lru_cache(maxsize=8)
def _morse_box(morse: Morse, resolution: float, order: int, ndim: int = 2) -> tuple[np.ndarray, np.ndarray, int, int]:
    """rho_I over a box of cell offsets, and the flat code of each stencil move in it.

    With R = ``_OFFSET_RADIUS`` and r = floor(sqrt(order)), the robots' offset at the end
    of a step, d = d0 + o_a - o_b, lies in the box |d_k| <= R + 2r whenever the start
    offset d0 lies in |d_k| <= R (every axis k). Its flat index in the box (row-major,
    side 2B + 1, B = R + 2r) is linear in d: ``G(d0) + code[a] - code[b]``, G(d0) the
    flat index of d0 + B (in 2-D, (dx0 + B) (2B + 1) + (dy0 + B)) and code[s] the strides
    times move s, so one edge's (L, L) table is one subtraction and one gather, whatever
    its label sets.

    Returns
    -------
    table
        ((2B + 1)^d,) rho_I of each offset of the box (read-only).
    code
        (S,) int32 flat offset of each stencil move.
    R, B
        The start offset radius and the box radius.
    """
    off = stencil(order, ndim)
    R = _OFFSET_RADIUS
    B = R + 2 * int(np.floor(np.sqrt(order)))
    width = 2 * B + 1
    axes = np.meshgrid(*([np.arange(-B, B + 1)] * ndim), indexing="ij")
    table = _morse_table(morse, resolution)(np.sum([x * x for x in axes], axis=0).ravel())
    code = (off @ (width ** np.arange(ndim - 1, -1, -1))).astype(np.int32)
    table.setflags(write=False)
    code.setflags(write=False)
    return table, code, R, B


def pairwise_tables(labels: LabelSets, edges: np.ndarray, weights: np.ndarray, morse: Morse,
                    resolution: float) -> np.ndarray:
    """(E, L, L) w_ij rho_I(|x_i - x_j|) for every label pair of every edge.

    Padding labels repeat "stay", so their entries are finite and never chosen (their
    unary is inf); they need no special value. The distance depends only on the start
    offset and the two stencil moves: edges whose start offset lies within
    ``_OFFSET_RADIUS`` gather their table from :func:`_morse_box`; longer edges (a
    stretched graph) compute their squared distances directly.
    """
    L = labels.index.shape[1]
    if not len(edges):
        return np.zeros((0, L, L))
    ndim = labels.ndim
    table, code, R, B = _morse_box(morse, resolution, labels.order, ndim)
    ia, ib = labels.index[edges[:, 0]], labels.index[edges[:, 1]]
    d0 = labels.starts[edges[:, 0]] - labels.starts[edges[:, 1]]
    far = np.flatnonzero(np.any(np.abs(d0) > R, axis=1))
    dc = np.clip(d0, -R, R)  # far edges gather a placeholder, replaced below
    g = ((dc + B) @ ((2 * B + 1) ** np.arange(ndim - 1, -1, -1))).astype(np.int32)
    first = code.take(ia)
    first += g[:, None]  # (E, L): G(d0) + code[a]
    second = code.take(ib)  # (E, L): code[b]
    out = np.empty((len(edges), L, L))
    # in chunks: small temporaries are reused by the allocator instead of being mapped
    # (and page-faulted) afresh every step
    w = weights.astype(float)[:, None, None]
    for a in range(0, len(edges), _CHUNK):
        b = a + _CHUNK
        table.take(first[a:b, :, None] - second[a:b, None, :], out=out[a:b])
        out[a:b] *= w[a:b]  # while the chunk is in cache
    if len(far):
        off = stencil(labels.order, ndim)
        d = d0[far][:, None, None, :] + off[ia[far]][:, :, None, :] - off[ib[far]][:, None, :, :]
        out[far] = _morse_table(morse, resolution)((d ** 2).sum(axis=-1)) * w[far]
    return out


def step_mrf(labels: LabelSets, weights: CliqueWeights, static: np.ndarray, morse: Morse,
             resolution: float, downwash: float = 1.0, priority: np.ndarray | None = None) -> PairwiseMRF:
    """The pairwise MRF of one step, with ``initial`` = everybody stays (label 0).

    ``downwash`` = c sets the metric of the hard conflicts (:func:`conflict_tables`); ``priority`` (N,), the
    order sequential optimizers visit the robots in (:attr:`solvers.mrf.PairwiseMRF.priority`).
    """
    cells = labels.cells
    valid = labels.valid
    N = valid.shape[0]
    unary = weights.node[:, None] * cell_values(static, cells)
    unary = np.where(valid, unary, np.inf)
    e = weights.edges
    pairwise = pairwise_tables(labels, e, weights.edge, morse, resolution)
    pairs, mask = conflict_tables(labels, downwash)
    return PairwiseMRF(unary=unary, edges=e, pairwise=pairwise, conflicts=pairs, conflict_mask=mask,
                       initial=np.zeros(N, dtype=np.intp), priority=priority)
