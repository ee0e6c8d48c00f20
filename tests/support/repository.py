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


def cites_a_year(doc: str | None) -> bool:
    """Whether a backend module's docstring gives its paper's year (docs/extending.md: "cites its paper with its
    year"): any year of 1900 to 2099. The QP test took 1990 to 2029 only, and refused a backend that cited SLSQP's
    paper (Kraft, 1988) or the dual active-set method of quadprog (Goldfarb and Idnani, 1983), a library tour."""
    import re

    return bool(doc) and re.search(r"(?<!\d)(19|20)\d\d(?!\d)", doc or "") is not None
