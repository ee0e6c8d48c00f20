"""The interactive view of a run: map, discrete paths and trajectories in 3-D, one HTML file.

:func:`scene` builds a plotly figure; :func:`write_scene` writes it as a self-contained
HTML page (plotly.js inlined, so it opens offline) that can be turned, zoomed and hovered.

The occupied voxels are drawn as their surface only: the faces between an occupied voxel
and a free one (or the map's edge), merged into rectangles (:func:`voxel_faces`: runs of
faces along one axis of their plane, then runs of equal runs along the other), two
triangles each. A box of voxels is then its six faces whatever its size, so the file
grows with the obstacles' surface, not with the map's volume. The discrete paths join
voxel centres; the trajectories are sampled polynomials. All robots share one trace per
kind (coloured by robot, with gaps between robots), so a swarm of a thousand is a
handful of traces.

A 2-D run can be shown too: its cells become one layer of voxels at the flight altitude
and its points get that altitude as z.

plotly is imported here only, when a scene is built.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from mrfswarm.maps import OccupancyGrid

#: Most trajectory samples (robots x times) a scene holds; above it the times are thinned.
MAX_SAMPLES = 200_000
#: Opacity of the obstacles' surface (the paths behind and inside stay visible).
OBSTACLE_OPACITY = 0.35


def voxel_faces(occupied: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The surface of the occupied voxels as axis-aligned rectangles, in voxel-corner coordinates.

    Voxel ``(i, j, k)`` spans ``[i, i + 1] x [j, j + 1] x [k, k + 1]`` in these coordinates.
    A face is exposed when the voxel on its other side is free or off the map.

    Parameters
    ----------
    occupied
        (W, H, D) bool.

    Returns
    -------
    lo, hi : numpy.ndarray
        (F, 3) int corners of each rectangle; ``lo[f, a] == hi[f, a]`` on its normal axis.
    normal : numpy.ndarray
        (F,) int, +-(a + 1): the normal axis a and the side (outwards) it faces.
    """
    occ = np.asarray(occupied, dtype=bool)
    if occ.ndim != 3:
        raise ValueError(f"voxel_faces: expected a (W, H, D) array, got shape {occ.shape}")
    los, his, normals = [], [], []
    for a in range(3):
        u, w = [b for b in range(3) if b != a]
        for side in (-1, 1):
            pad = [(0, 0)] * 3
            pad[a] = (1, 1)
            neighbour = np.roll(np.pad(occ, pad), -side, axis=a)
            sl = [slice(None)] * 3
            sl[a] = slice(1, -1)
            exposed = occ & ~neighbour[tuple(sl)]
            # runs along u: move (a, w, u) to the front and the end, find where runs start and stop
            e = np.transpose(exposed, (a, w, u))
            e = np.pad(e, [(0, 0), (0, 0), (1, 1)]).astype(np.int8)
            step = np.diff(e, axis=-1)
            starts = np.argwhere(step == 1)  # (plane, w, u0), in C order
            ends = np.argwhere(step == -1)[:, 2]  # u1 (exclusive), paired with starts in the same order
            if not len(starts):
                continue
            # runs of equal (plane, u0, u1) at consecutive w merge into one rectangle
            plane, ws, u0, u1 = starts[:, 0], starts[:, 1], starts[:, 2], ends
            order = np.lexsort((ws, u1, u0, plane))
            plane, ws, u0, u1 = plane[order], ws[order], u0[order], u1[order]
            new = np.ones(len(ws), dtype=bool)
            new[1:] = ((plane[1:] != plane[:-1]) | (u0[1:] != u0[:-1]) | (u1[1:] != u1[:-1])
                       | (ws[1:] != ws[:-1] + 1))
            first = np.flatnonzero(new)
            last = np.append(first[1:], len(ws)) - 1
            lo = np.empty((len(first), 3), dtype=np.int64)
            hi = np.empty_like(lo)
            lo[:, a] = hi[:, a] = plane[first] + (side > 0)
            lo[:, u], hi[:, u] = u0[first], u1[first]
            lo[:, w], hi[:, w] = ws[first], ws[last] + 1
            los.append(lo)
            his.append(hi)
            normals.append(np.full(len(first), side * (a + 1)))
    if not los:
        return np.zeros((0, 3), dtype=np.int64), np.zeros((0, 3), dtype=np.int64), np.zeros(0, dtype=np.int64)
    return np.concatenate(los), np.concatenate(his), np.concatenate(normals)


def face_mesh(grid: OccupancyGrid) -> tuple[np.ndarray, np.ndarray]:
    """The occupied voxels' surface as a triangle mesh in world coordinates: vertices (4F, 3), triangles (2F, 3)."""
    lo, hi, normal = voxel_faces(grid.occupied)
    F = len(lo)
    a = np.abs(normal) - 1
    u, w = (a + 1) % 3, (a + 2) % 3  # the plane's axes, in right-handed order about the normal
    corners = np.repeat(lo[:, None, :], 4, axis=1).astype(float)
    rows = np.arange(F)
    for k, (du, dw) in enumerate(((0, 0), (1, 0), (1, 1), (0, 1))):
        if du:
            corners[rows, k, u] = hi[rows, u]
        if dw:
            corners[rows, k, w] = hi[rows, w]
    world = np.asarray(grid.origin) + grid.resolution * (corners - 0.5)
    base = 4 * rows[:, None]
    tris = np.concatenate([base + [0, 1, 2], base + [0, 2, 3]])
    return world.reshape(-1, 3), tris


def _lift(points: np.ndarray, altitude: float) -> np.ndarray:
    """Points (..., d) as (..., 3): a 2-D point flies at ``altitude``."""
    p = np.asarray(points, dtype=float)
    if p.shape[-1] == 3:
        return p
    return np.concatenate([p, np.full(p.shape[:-1] + (1,), altitude)], axis=-1)


def _gapped(curves: np.ndarray) -> np.ndarray:
    """(N, S, 3) curves as one (N (S + 1), 3) polyline with a NaN row after each curve (plotly's gap)."""
    N, S, _ = curves.shape
    out = np.full((N, S + 1, 3), np.nan)
    out[:, :S] = curves
    return out.reshape(-1, 3)


def scene(grid: OccupancyGrid, discrete: np.ndarray, samples: np.ndarray | None = None,
          times: np.ndarray | None = None, goal: np.ndarray | None = None, altitude: float = 1.0,
          title: str = ""):
    """A plotly figure of the map's obstacles, the discrete paths and the trajectories.

    Parameters
    ----------
    grid
        The map, 2 or 3 axes (a 2-D map is one layer of cells at ``altitude``).
    discrete
        (T + 1, N, d) the discrete paths, metres.
    samples
        (S, N, d) the trajectories sampled at ``times`` (S,), or None.
    goal
        (d,) or None.
    altitude
        z of a 2-D run.
    title
        The figure's title.

    Returns
    -------
    plotly.graph_objects.Figure
    """
    import plotly.graph_objects as go

    if grid.ndim == 2:
        grid = OccupancyGrid(np.asarray(grid.prob)[..., None], grid.resolution, (*grid.origin, altitude))
    discrete = _lift(discrete, altitude)
    N = discrete.shape[1]
    robot_ids = np.arange(N)
    colorscale = "Turbo"
    traces = []
    vertices, tris = face_mesh(grid)
    if len(tris):
        traces.append(go.Mesh3d(x=vertices[:, 0], y=vertices[:, 1], z=vertices[:, 2], i=tris[:, 0], j=tris[:, 1],
                                k=tris[:, 2], color="rgb(140,140,150)", opacity=OBSTACLE_OPACITY, flatshading=True,
                                lighting={"ambient": 0.55, "diffuse": 0.7, "specular": 0.05}, hoverinfo="skip",
                                name="obstacles", showlegend=True))
    lo, hi = grid.bounds
    box = np.array([[lo[0], lo[1], lo[2]], [hi[0], lo[1], lo[2]], [hi[0], hi[1], lo[2]], [lo[0], hi[1], lo[2]]])
    top = box.copy()
    top[:, 2] = hi[2]
    edges = [np.array([box[k], box[(k + 1) % 4]]) for k in range(4)] + \
            [np.array([top[k], top[(k + 1) % 4]]) for k in range(4)] + [np.array([box[k], top[k]]) for k in range(4)]
    frame = _gapped(np.stack(edges))
    traces.append(go.Scatter3d(x=frame[:, 0], y=frame[:, 1], z=frame[:, 2], mode="lines", name="map bounds",
                               line={"color": "rgb(170,170,170)", "width": 2}, hoverinfo="skip"))
    d = _gapped(discrete.transpose(1, 0, 2))
    d_robot = np.repeat(robot_ids, discrete.shape[0] + 1)
    traces.append(go.Scatter3d(x=d[:, 0], y=d[:, 1], z=d[:, 2], mode="lines+markers", name="discrete paths",
                               line={"color": "rgb(90,90,90)", "width": 2, "dash": "dot"},
                               marker={"size": 2, "color": "rgb(90,90,90)"}, customdata=d_robot,
                               hovertemplate="robot %{customdata}<br>(%{x:.2f}, %{y:.2f}, %{z:.2f})<extra></extra>"))
    if samples is not None:
        samples = _lift(samples, altitude)
        times = np.arange(len(samples), dtype=float) if times is None else np.asarray(times, dtype=float)
        every = max(1, int(np.ceil(samples.shape[0] * N / MAX_SAMPLES)))
        keep = np.unique(np.append(np.arange(0, len(samples), every), len(samples) - 1))
        s = _gapped(samples[keep].transpose(1, 0, 2))
        robot = np.repeat(robot_ids, len(keep) + 1).astype(float)
        t = np.tile(np.append(times[keep], np.nan), N)
        traces.append(go.Scatter3d(
            x=s[:, 0], y=s[:, 1], z=s[:, 2], mode="lines", name="trajectories",
            line={"color": robot, "colorscale": colorscale, "cmin": 0, "cmax": max(1, N - 1), "width": 4},
            customdata=np.stack([robot, t], axis=1),
            hovertemplate="robot %{customdata[0]:.0f}, t = %{customdata[1]:.2f} s<br>"
                          "(%{x:.2f}, %{y:.2f}, %{z:.2f})<extra></extra>"))
    first, last = (discrete[0], discrete[-1]) if samples is None else (samples[0], samples[-1])
    for name, p, color in (("start", first, "rgb(44,160,44)"), ("end", last, "rgb(31,119,180)")):
        traces.append(go.Scatter3d(x=p[:, 0], y=p[:, 1], z=p[:, 2], mode="markers", name=name,
                                   marker={"size": 4, "color": color, "line": {"color": "black", "width": 1}},
                                   customdata=robot_ids,
                                   hovertemplate=f"robot %{{customdata}} {name}<br>(%{{x:.2f}}, %{{y:.2f}}, "
                                                 f"%{{z:.2f}})<extra></extra>"))
    if goal is not None:
        g = _lift(np.asarray(goal, dtype=float)[None], altitude)
        traces.append(go.Scatter3d(x=g[:, 0], y=g[:, 1], z=g[:, 2], mode="markers", name="goal",
                                   marker={"size": 8, "color": "gold", "symbol": "diamond",
                                           "line": {"color": "black", "width": 1}}))
    fig = go.Figure(traces)
    fig.update_layout(
        title={"text": title}, height=720, margin={"l": 0, "r": 0, "t": 40, "b": 0},
        legend={"itemsizing": "constant"},
        scene={"aspectmode": "data", "xaxis": {"title": {"text": "x [m]"}, "range": [lo[0], hi[0]]},
               "yaxis": {"title": {"text": "y [m]"}, "range": [lo[1], hi[1]]},
               "zaxis": {"title": {"text": "z [m]"}, "range": [lo[2], hi[2]]},
               "camera": {"eye": {"x": -0.9, "y": -1.6, "z": 0.9}}})
    return fig


def write_scene(path: Path, grid: OccupancyGrid, discrete: np.ndarray, samples: np.ndarray | None = None,
                times: np.ndarray | None = None, goal: np.ndarray | None = None, altitude: float = 1.0,
                title: str = "") -> Path:
    """:func:`scene` as a self-contained HTML file (plotly.js inlined: no network needed to open it)."""
    fig = scene(grid, discrete, samples, times, goal, altitude, title)
    fig.write_html(str(path), include_plotlyjs=True, full_html=True, config={"displaylogo": False})
    return Path(path)
