"""Random swarms on random maps, the inputs of the indexed-against-all-pairs tests."""

from __future__ import annotations

import numpy as np


def random_start(rng: np.random.Generator, n: int, W: int, H: int, p_blocked: float) -> tuple[np.ndarray, np.ndarray]:
    """A ``W x H`` free-cell mask (each cell blocked with probability ``p_blocked``) and ``n`` distinct free cells.

    Returns ``(free, pos)``: ``free`` of shape ``(W, H)``, ``pos`` of shape ``(n, 2)``.
    """
    free = rng.random((W, H)) > p_blocked
    cells = np.argwhere(free)
    return free, cells[rng.choice(len(cells), n, replace=False)]
