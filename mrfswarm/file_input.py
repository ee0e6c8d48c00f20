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
    """The text of ``path`` (UTF-8, a byte-order mark skipped: some editors save one, and TOML refused it at line 1,
    column 1), as :func:`read_bytes` for errors; a file that is not UTF-8 text is one too."""
    try:
        return path.read_text(encoding="utf-8-sig")
    except OSError as e:
        raise error(f"cannot read {what} {str(path)!r}: {e.strerror or e}") from e
    except UnicodeDecodeError as e:
        raise error(f"cannot read {what} {str(path)!r}: not UTF-8 text (byte {e.start})") from None
