"""Where the tests find the repository's files, the same from any folder under ``tests/``."""

from __future__ import annotations

from pathlib import Path

#: The repository's root (``pyproject.toml``, ``experiments/``, ``tests/``).
ROOT = Path(__file__).resolve().parents[2]
#: The scenario configs and maps of ``experiments/``.
EXPERIMENTS = ROOT / "experiments"
#: Input files of the tests: ``tests/data/``.
TEST_DATA = ROOT / "tests" / "data"
