"""Where the tests find the repository's files, the same from any folder under ``tests/``."""

from __future__ import annotations

from pathlib import Path

#: The repository's root (``pyproject.toml``, ``experiments/``, ``tests/``).
ROOT = Path(__file__).resolve().parents[2]
#: The scenario configs and maps of ``experiments/``.
EXPERIMENTS = ROOT / "experiments"
#: Input files of the tests: ``tests/data/``.
TEST_DATA = ROOT / "tests" / "data"


def declared_extras(distribution: str = "") -> set[str]:
    """The extras a distribution declares: ``distribution``'s installed metadata (a plugin's record names its own,
    ``Backend.distribution``), or this repository's ``pyproject.toml`` for a built-in record (empty name)."""
    if distribution:
        from importlib.metadata import metadata

        return set(metadata(distribution).get_all("Provides-Extra") or [])
    import tomllib

    return set(tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"])
