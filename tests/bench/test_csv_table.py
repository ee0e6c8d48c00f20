"""The benchmarks' table writers (experiments/bench/csv_table.py): the CSV and the text table hold the same cells."""

from __future__ import annotations

import csv
import sys

from support.repository import EXPERIMENTS

sys.path.insert(0, str(EXPERIMENTS / "bench"))
from csv_table import text_table, write_csv  # noqa: E402

ROWS = [{"case": "doorway", "x_bound": 1.324, "steps": 17}, {"case": "clutter40", "steps": 67}]


def test_the_csv_and_the_text_table_hold_the_same_cells(tmp_path):
    out = tmp_path / "deep" / "t.csv"
    write_csv(out, ROWS, float_format=".2f")
    with open(out, newline="") as f:
        read = list(csv.DictReader(f))
    assert read == [{"case": "doorway", "x_bound": "1.32", "steps": "17"},
                    {"case": "clutter40", "x_bound": "", "steps": "67"}]  # a missing key is an empty cell
    lines = text_table(ROWS, ["case", "steps"], width=10).splitlines()
    assert lines == ["      case      steps", "   doorway         17", " clutter40         67"]
    assert text_table(ROWS, sep="|").splitlines()[0].split("|") == [f"{k:>9}" for k in ROWS[0]]
