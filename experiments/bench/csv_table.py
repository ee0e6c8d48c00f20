"""The benchmarks' one CSV writer: a list of row dicts to a file, its folder made; and the same rows as a
plain text table."""

from __future__ import annotations

import csv
from pathlib import Path


def write_csv(path: Path, rows: list[dict], columns: list[str] | None = None, float_format: str | None = None) -> None:
    """Write ``rows`` to ``path`` with a header of ``columns`` (default: the first row's keys).

    A key a row lacks is written empty; with ``float_format`` (e.g. ``".6g"``) floats are
    formatted with it.
    """
    columns = list(rows[0]) if columns is None else columns
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=columns)
        w.writeheader()
        for r in rows:
            w.writerow({c: _cell(r.get(c, ""), float_format) for c in columns})


def _cell(value, float_format: str | None):
    return format(value, float_format) if float_format and isinstance(value, float) else value


def text_table(rows: list[dict], columns: list[str] | None = None, width: int = 9, sep: str = " ") -> str:
    """``rows`` as right-aligned text columns of ``width`` under a header of ``columns`` (default: the first row's
    keys)."""
    columns = list(rows[0]) if columns is None else columns
    lines = [sep.join(f"{c:>{width}}" for c in columns)]
    lines += [sep.join(f"{r.get(c, '')!s:>{width}}" for c in columns) for r in rows]
    return "\n".join(lines)
