"""Character grids (ascii rows, MovingAI maps) to P(occupied) arrays, one table lookup.

Column x and row y as in the text, row 0 the first line, no flip: the character at
row y, column x becomes ``prob[x, y]``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class BadCharacter:
    """The first character of a grid that is not in the alphabet."""

    row: int
    column: int
    char: str


def lookup_table(free: str, occupied: str) -> np.ndarray:
    """256 entries: 0.0 for ``free`` bytes, 1.0 for ``occupied`` ones, NaN for the rest."""
    table = np.full(256, np.nan)
    table[np.frombuffer(free.encode("ascii"), np.uint8)] = 0.0
    table[np.frombuffer(occupied.encode("ascii"), np.uint8)] = 1.0
    return table


def decode(rows: list[str], table: np.ndarray) -> np.ndarray | BadCharacter:
    """``prob`` (W, H) from equal-length rows, or the first character not in ``table``.

    Characters outside ASCII are bad characters too (reported as they are).
    """
    width = len(rows[0])
    try:
        data = np.frombuffer("".join(rows).encode("ascii"), np.uint8).reshape(len(rows), width)
    except UnicodeEncodeError:
        for y, row in enumerate(rows):
            for x, ch in enumerate(row):
                if ord(ch) > 127 or np.isnan(table[ord(ch)]):
                    return BadCharacter(y, x, ch)
        raise AssertionError("unreachable: a non-ASCII character was not found") from None
    prob = table[data]  # (H, W): row y, column x
    bad = np.isnan(prob)
    if bad.any():
        y, x = np.argwhere(bad)[0]
        return BadCharacter(int(y), int(x), rows[y][x])
    return np.ascontiguousarray(prob.T)


def encode(occupied: np.ndarray, free_char: str, occupied_char: str) -> list[str]:
    """Rows of text (row y = line y) from an occupied (W, H) bool array."""
    chars = np.where(occupied.T, ord(occupied_char), ord(free_char)).astype(np.uint8)
    return [row.tobytes().decode("ascii") for row in chars]
