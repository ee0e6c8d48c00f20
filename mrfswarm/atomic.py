"""Files written whole or not at all, with the permissions of a file created the usual way.

A file is written under a temporary name beside its target and renamed onto it, so a
reader (or a run killed half-way) never sees half a file. :func:`tempfile.mkstemp`
creates that temporary file readable by its owner alone (mode 0600); before the rename it
gets the mode ``open()`` would have given it, 0666 less the process's umask (0644 under the
usual umask 022), so a run's outputs are readable by whoever may read its folder.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable
from pathlib import Path


def umask() -> int:
    """The process's umask. It can only be read by setting it, so it is set and put back at once
    (the one moment another thread creating a file would see 022)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def file_mode() -> int:
    """0666 less the umask: the mode ``open(path, "w")`` gives a new file."""
    return 0o666 & ~umask()


def not_writable(folder: Path) -> str | None:
    """Why no file can be made in ``folder`` (an existing folder), or None when one can: a file written there
    after the work is done failed with a traceback, the work lost (``--out`` on a read-only file system)."""
    if os.access(folder, os.W_OK | os.X_OK):
        return None
    if os.statvfs(folder).f_flag & os.ST_RDONLY:
        return f"{str(folder)!r} is on a read-only file system"
    return f"{str(folder)!r} is not writable (permission denied)"


def atomic_write(path: Path, write: Callable[[Path], object]) -> Path:
    """Call ``write(tmp)`` (its return value is ignored) then rename ``tmp`` to ``path`` (same folder, same
    suffix), the folder made if needed; ``tmp`` gets :func:`file_mode` first. Nothing is left at ``path``
    (and no ``tmp``) if ``write`` fails."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.stem}.", suffix=path.suffix)
    os.close(fd)
    try:
        write(Path(tmp))
        os.chmod(tmp, file_mode())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path
