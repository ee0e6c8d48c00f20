"""Metrics of discrete paths: separation (within steps too), cohesion, clearance, lengths.

Distances are reported in metres. Within a step robots move in straight lines at the same
time (the discrete stage's motion model), so the minimum separation accounts for the
closest approach during every step, over all robot pairs (not only graph neighbours).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree
from scipy.spatial.distance import pdist

from mrfswarm.geometry import point_box_distance
from mrfswarm.motion import step_min_separation

#: Samples per step when measuring obstacle clearance along straight moves.
_CLEARANCE_SAMPLES = 16


@dataclass(frozen=True)
class DiscreteMetrics:
    """Summary of the discrete paths (metres)."""

    min_separation: float
    mean_distance: np.ndarray
    min_distance: np.ndarray
    min_obstacle_clearance: float | None
    path_lengths: np.ndarray
    steps: int
    reached_goal: bool | None
    final_goal_distance: float | None


def min_separation(paths: np.ndarray) -> float:
    """Smallest distance (cells) between two robots over all steps, during moves included."""
    if paths.shape[1] < 2:
        return float("inf")
    if len(paths) == 1:
        return float(pdist(paths[0].astype(float)).min())
    return min(step_min_separation(paths[t], paths[t + 1])[0] for t in range(len(paths) - 1))


def pairwise_distance_stats(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per row of ``points`` (T, N, 2): mean and min distance over all robot pairs."""
    mean = np.empty(len(points))
    mn = np.empty(len(points))
    for t, p in enumerate(points):
        d = pdist(p.astype(float)) if len(p) > 1 else np.array([np.nan])
        mean[t], mn[t] = d.mean(), d.min()
    return mean, mn


def obstacle_clearance(occupied: np.ndarray, points: np.ndarray) -> float | None:
    """Smallest distance (cells) from any point (..., 2), in cell coordinates, to an occupied square.

    None when the map has no obstacle. Exact: the nearest squares are among the nearest
    occupied cell centres.
    """
    occ = np.argwhere(occupied)
    if len(occ) == 0:
        return None
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    k = min(8, len(occ))
    _, idx = cKDTree(occ).query(pts, k)
    idx = np.asarray(idx).reshape(len(pts), k)
    d = point_box_distance(pts[:, None, :], occ[idx].astype(float))
    return float(d.min())


def densify(paths: np.ndarray, samples: int = _CLEARANCE_SAMPLES) -> np.ndarray:
    """Points along the straight moves of ``paths`` (T + 1, N, 2), ``samples`` per step."""
    if len(paths) == 1:
        return paths.astype(float)
    s = np.linspace(0.0, 1.0, samples, endpoint=False)[:, None, None, None]
    a = paths[:-1].astype(float)[None]
    b = paths[1:].astype(float)[None]
    pts = (a + s * (b - a)).transpose(1, 0, 2, 3).reshape(-1, paths.shape[1], 2)
    return np.concatenate([pts, paths[-1:].astype(float)])


def discrete_metrics(paths: np.ndarray, occupied: np.ndarray, resolution: float = 1.0,
                     goal: np.ndarray | None = None, goal_radius: float | None = None) -> DiscreteMetrics:
    """All metrics of discrete paths (T + 1, N, 2) in cells, reported in metres.

    ``reached_goal``: the swarm's centroid at the end within ``goal_radius`` metres of the
    goal (None without a goal).
    """
    mean_d, min_d = pairwise_distance_stats(paths)
    clearance = obstacle_clearance(occupied, densify(paths))
    steps = np.diff(paths.astype(float), axis=0)
    lengths = np.hypot(steps[..., 0], steps[..., 1]).sum(axis=0) * resolution if len(steps) else np.zeros(paths.shape[1])
    reached = dist = None
    if goal is not None:
        dist = float(np.hypot(*(paths[-1].mean(axis=0) - goal))) * resolution
        reached = bool(goal_radius is not None and dist <= goal_radius)
    return DiscreteMetrics(
        min_separation=min_separation(paths) * resolution,
        mean_distance=mean_d * resolution,
        min_distance=min_d * resolution,
        min_obstacle_clearance=None if clearance is None else clearance * resolution,
        path_lengths=lengths,
        steps=len(paths) - 1,
        reached_goal=reached,
        final_goal_distance=dist,
    )
