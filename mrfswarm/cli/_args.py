"""Argument types shared by the subcommands: a bad value is argparse's one-line error, exit 2.

Each raises :class:`argparse.ArgumentTypeError` with what the value must be; argparse
turns it into ``mrfswarm: error: argument --seed: must be an integer >= 0, got '-5'``.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path


def seed(text: str) -> int:
    """A random seed: an integer >= 0 (numpy's generators take no negative seeds)."""
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be an integer >= 0, got {text!r}") from None
    if v < 0:
        raise argparse.ArgumentTypeError(f"must be an integer >= 0, got {text!r}")
    return v


def positive_float(text: str) -> float:
    """A finite number > 0."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a positive number, got {text!r}") from None
    if not (math.isfinite(v) and v > 0):
        raise argparse.ArgumentTypeError(f"must be a positive finite number, got {text!r}")
    return v


def output_dir(text: str) -> Path:
    """A folder to write into: it may not exist yet, but it may not be (or lie under) a file."""
    p = Path(text)
    for q in (p, *p.parents):
        if q.exists():
            if not q.is_dir():
                what = "is a file" if q == p else f"lies under the file {str(q)!r}"
                raise argparse.ArgumentTypeError(f"{text!r} {what}, not a folder")
            break
    return p
