"""Waypoint files (CSV with a header ``x,y`` or ``x,y,z``) and waypoint checks."""

from __future__ import annotations

import csv
import io
import os
from pathlib import Path

import numpy as np

from mrfswarm.errors import ScenarioError

HEADERS = (("x", "y"), ("x", "y", "z"))


def read_waypoints_csv(path: str | os.PathLike) -> np.ndarray:
    """Read waypoints from a CSV file with a header line ``x,y`` or ``x,y,z``.

    Blank lines are skipped. Returns an (n, 2) or (n, 3) array; see
    :func:`check_waypoints` for what is rejected besides malformed text.

    Raises
    ------
    ScenarioError
        Unreadable file, wrong header, wrong column count, a value that is not a
        finite number (the message names the line).
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")  # a byte-order mark, as spreadsheets save UTF-8 CSV, is skipped
    except OSError as e:
        raise ScenarioError(f"cannot read waypoints file {path}: {e.strerror or e}") from e
    except UnicodeDecodeError:
        raise ScenarioError(f"{path}: not a text file") from None
    lines = [(n, r) for n, r in enumerate(csv.reader(io.StringIO(text)), start=1) if r and any(c.strip() for c in r)]
    if not lines:
        raise ScenarioError(f"{path}: empty file; expected a header line x,y or x,y,z")
    n0, first = lines[0]
    header = tuple(c.strip().lower() for c in first)
    if header not in HEADERS:
        raise ScenarioError(f"{path}:{n0}: header must be x,y or x,y,z, got {','.join(header)!r}")
    rows = []
    for n, r in lines[1:]:
        if len(r) != len(header):
            raise ScenarioError(f"{path}:{n}: expected {len(header)} values ({','.join(header)}), got {len(r)}")
        try:
            v = [float(c) for c in r]
        except ValueError:
            raise ScenarioError(f"{path}:{n}: not a number: {','.join(c.strip() for c in r)!r}") from None
        if not all(np.isfinite(v)):
            raise ScenarioError(f"{path}:{n}: values must be finite, got {','.join(c.strip() for c in r)!r}")
        rows.append(v)
    W = np.array(rows, dtype=float).reshape(-1, len(header))
    check_waypoints(W, source=str(path))
    return W


def check_waypoints(waypoints: np.ndarray, *, allow_repeats: bool = False, source: str = "waypoints") -> None:
    """Reject fewer than two waypoints, non-finite values and (unless allowed) repeats.

    A waypoint equal to the previous one makes a zero-length segment: fine with explicit
    durations (hovering), but a speed-based duration would be zero.

    Raises
    ------
    ScenarioError
        Naming the offending waypoint (0-based).
    """
    W = np.asarray(waypoints, dtype=float)
    if W.ndim != 2 or W.shape[0] < 2:
        raise ScenarioError(f"{source}: need at least two waypoints, got {0 if W.ndim != 2 else W.shape[0]}")
    if not np.all(np.isfinite(W)):
        i = int(np.argwhere(~np.isfinite(W))[0, 0])
        raise ScenarioError(f"{source}: waypoint {i} is not finite: {W[i].tolist()}")
    if not allow_repeats:
        same = np.all(W[1:] == W[:-1], axis=1)
        if np.any(same):
            i = int(np.argmax(same))
            raise ScenarioError(f"{source}: waypoints {i} and {i + 1} are the same point {W[i].tolist()}")
