"""The packages of an earlier git revision, for benchmarks that compare old and new code in one session.

A benchmark extracts ``mrfswarm`` and ``solvers`` at a revision into a temporary folder
and runs its measurement in a child process with that folder first on ``sys.path``
(the child checks that it imported the extracted code), next to a child running the
working tree.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tarfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def extract(ref: str, into: Path) -> Path:
    """``mrfswarm`` and ``solvers`` at git revision ``ref``, extracted under ``into``; returns the folder."""
    archive = into / "code.tar"
    subprocess.run(["git", "-C", str(ROOT), "archive", "--format=tar", "-o", str(archive), ref, "mrfswarm", "solvers"],
                   check=True)
    with tarfile.open(archive) as tar:
        tar.extractall(into / "code", filter="data")
    return into / "code"


def use(code: str | None) -> None:
    """In a child: import ``mrfswarm`` from ``code`` (None: the working tree), and check it did."""
    if code:
        sys.path.insert(0, code)
    import mrfswarm

    if code and not mrfswarm.__file__.startswith(code):
        raise SystemExit(f"imported {mrfswarm.__file__}, not the code under {code}")


def run_child(script: Path, args: list[str], code: Path | None) -> dict:
    """Run ``script args [--code CODE]`` and return the JSON object its last output line holds."""
    cmd = [sys.executable, str(script), *args] + (["--code", str(code)] if code else [])
    proc = subprocess.run(cmd, capture_output=True, text=True, env={**os.environ, "PYTHONHASHSEED": "0"}, cwd=ROOT,
                          check=False)
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{proc.stderr[-3000:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def drop_unknown_keys(data: dict) -> None:
    """Remove from the TOML ``data`` the keys of each section that the imported code's config does not know: an
    earlier revision refuses them (``unknown config key mrf.follow``), and a config that sets a later rule sets
    it to the earlier behaviour, its only one."""
    import dataclasses

    from mrfswarm.config import Config

    sections = {f.name: f for f in dataclasses.fields(Config)}
    for name, table in data.items():
        f = sections.get(name)
        if f is None or not isinstance(table, dict):
            continue
        default = f.default_factory() if f.default_factory is not dataclasses.MISSING else f.default
        if not dataclasses.is_dataclass(default):
            continue
        known = {g.name for g in dataclasses.fields(default)}
        for key in [k for k in table if k not in known]:
            del table[key]
