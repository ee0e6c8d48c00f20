"""Reading an input file, with the error a user can act on when it cannot be read."""

from __future__ import annotations

from pathlib import Path

from mrfswarm.errors import MrfswarmError, ScenarioError


def read_bytes(path: Path, what: str, error: type[MrfswarmError] = ScenarioError) -> bytes:
    """The bytes of ``path``; ``error`` naming ``what`` and the file when it cannot be read."""
    try:
        return path.read_bytes()
    except OSError as e:
        raise error(f"cannot read {what} {str(path)!r}: {e.strerror or e}") from e


def read_text(path: Path, what: str, error: type[MrfswarmError] = ScenarioError) -> str:
    """The text of ``path`` (the locale's encoding), as :func:`read_bytes` for errors."""
    try:
        return path.read_text()
    except OSError as e:
        raise error(f"cannot read {what} {str(path)!r}: {e.strerror or e}") from e
