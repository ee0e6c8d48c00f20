"""The uav_trajectories / Crazyswarm polynomial CSV format.

Header ``duration,x^0,...,x^7,y^0,...,y^7,z^0,...,z^7,yaw^0,...,yaw^7``; one row per
piece; coefficients in increasing power of the piece's local time (the same convention
as :class:`~mrfswarm.trajectory.polynomial.PiecewisePolynomial`). A 2-D trajectory is
written with ``z`` constant at the given altitude, and ``yaw`` is always 0 unless a
yaw trajectory is given. A degree below 7 is zero-padded; a degree above 7 cannot be
written (it would have to be truncated, which changes the trajectory).
"""

from __future__ import annotations

import csv
import io
import os
from pathlib import Path

import numpy as np

from mrfswarm.atomic import atomic_write
from mrfswarm.errors import ScenarioError
from mrfswarm.trajectory.polynomial import PiecewisePolynomial
from solvers.errors import InvalidProblem

DEGREE = 7
AXES = ("x", "y", "z", "yaw")
HEADER = ["duration"] + [f"{a}^{k}" for a in AXES for k in range(DEGREE + 1)]


def to_rows(trajectory: PiecewisePolynomial, altitude: float = 1.0) -> np.ndarray:
    """(M, 33) rows of the format: duration, then 8 coefficients for x, y, z and yaw.

    Parameters
    ----------
    trajectory
        1-D (x), 2-D (x, y), 3-D (x, y, z) or 4-D (x, y, z, yaw), degree <= 7.
    altitude
        z for 1-D and 2-D trajectories.

    Raises
    ------
    InvalidProblem
        Degree above 7 or dimension above 4.
    """
    if trajectory.degree > DEGREE:
        raise InvalidProblem(
            f"a degree-{trajectory.degree} trajectory cannot be exported to the uav_trajectories CSV, "
            f"which holds degree <= {DEGREE} (truncating would change it); smooth with degree {DEGREE}"
        )
    if trajectory.dim > 4:
        raise InvalidProblem(f"the uav_trajectories CSV holds at most x, y, z, yaw; got dimension {trajectory.dim}")
    if not np.isfinite(altitude):
        raise InvalidProblem(f"altitude must be finite, got {altitude}")
    M = trajectory.pieces
    a = trajectory.with_degree(DEGREE).coefficients  # (M, 8, dim)
    coeffs = np.zeros((M, 4, DEGREE + 1))
    coeffs[:, : trajectory.dim, :] = np.moveaxis(a, 2, 1)
    if trajectory.dim < 3:
        coeffs[:, 2, 0] = altitude
    return np.concatenate([trajectory.durations[:, None], coeffs.reshape(M, -1)], axis=1)


def format_csv(trajectory: PiecewisePolynomial, altitude: float = 1.0) -> str:
    """The CSV text (full double precision, ``repr`` of each float)."""
    rows = to_rows(trajectory, altitude)
    buf = io.StringIO()
    buf.write(",".join(HEADER) + "\n")
    for r in rows:
        buf.write(",".join(repr(float(v)) for v in r) + "\n")
    return buf.getvalue()


def write_uav_csv(trajectory: PiecewisePolynomial, path: str | os.PathLike, altitude: float = 1.0) -> None:
    """Write ``trajectory`` to ``path`` atomically (a temporary file renamed into place).

    Nothing is left at ``path`` if formatting or writing fails.
    """
    text = format_csv(trajectory, altitude)
    write_text_atomic(path, text)


def write_text_atomic(path: str | os.PathLike, text: str) -> None:
    """Write ``text`` to a temporary file beside ``path``, then rename it onto ``path``."""
    atomic_write(Path(path), lambda p: p.write_text(text, newline=""))


def read_uav_csv(path: str | os.PathLike, dim: int = 3) -> PiecewisePolynomial:
    """Read a uav_trajectories CSV into a degree-7 trajectory.

    Parameters
    ----------
    path
        The file.
    dim
        Keep the first ``dim`` of x, y, z, yaw (2 for a planar trajectory).

    Raises
    ------
    ScenarioError
        Missing file, wrong header, malformed or non-finite values, non-positive durations.
    """
    if dim not in (1, 2, 3, 4):
        raise InvalidProblem(f"dim must be 1..4, got {dim}")
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as e:
        raise ScenarioError(f"cannot read trajectory file {path}: {e.strerror or e}") from e
    except UnicodeDecodeError:
        raise ScenarioError(f"{path}: not a text file") from None
    rows = [r for r in csv.reader(io.StringIO(text)) if r and any(c.strip() for c in r)]
    if not rows:
        raise ScenarioError(f"{path}: empty trajectory file")
    header = [c.strip() for c in rows[0]]
    if header != HEADER:
        raise ScenarioError(f"{path}: header must be {','.join(HEADER[:3])},...,yaw^7 (33 columns), got {len(header)} columns")
    data = []
    for n, r in enumerate(rows[1:], start=2):
        if len(r) != len(HEADER):
            raise ScenarioError(f"{path}:{n}: expected {len(HEADER)} values, got {len(r)}")
        try:
            data.append([float(c) for c in r])
        except ValueError as e:
            raise ScenarioError(f"{path}:{n}: not a number ({e})") from None
    if not data:
        raise ScenarioError(f"{path}: no pieces")
    arr = np.array(data)
    if not np.all(np.isfinite(arr)):
        n = int(np.argwhere(~np.isfinite(arr))[0, 0]) + 2
        raise ScenarioError(f"{path}:{n}: values must be finite")
    if np.any(arr[:, 0] <= 0):
        n = int(np.argmax(arr[:, 0] <= 0)) + 2
        raise ScenarioError(f"{path}:{n}: duration must be positive, got {arr[n - 2, 0]}")
    coeffs = arr[:, 1:].reshape(-1, 4, DEGREE + 1)[:, :dim, :]
    return PiecewisePolynomial(arr[:, 0], np.moveaxis(coeffs, 1, 2))
