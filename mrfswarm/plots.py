"""Figures in the paper's style: paths over the map, energy per step, distances over time.

matplotlib is imported here only (Agg backend); every function writes one PNG and
returns its path. Obstacles are grey, start positions green, end positions blue, as in
the paper's Fig. 6.

Many robots: lines are drawn as one ``LineCollection`` per figure element (one artist,
not one per robot). Above ``INDIVIDUAL_MAX`` robots a figure shows the swarm instead of
each robot: how long robots stayed in each cell as a density image and the paths of a
sample of ``HIGHLIGHT`` robots (spread over the swarm) in colour.

The dimension is data: a figure of a 3-D run (a voxel grid, positions (..., 3)) shows
the same drawing in three orthographic projections (:func:`views`): the top view x-y,
the side view x-z below it and the side view z-y beside it, sharing their axes (the
draughtsman's layout). A projected map shades each column by the fraction of its voxels
that are occupied, so a wall with a window is a lighter patch where the window is.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from mrfswarm.maps import OccupancyGrid


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


#: Up to this many robots, every robot gets its own colour.
INDIVIDUAL_MAX = 30
#: Robots drawn in colour when the swarm is drawn as a whole.
HIGHLIGHT = 12
#: Points per faint background curve (about the figure's width in pixels).
_FAINT_POINTS = 800


def highlighted(n: int, k: int = HIGHLIGHT) -> np.ndarray:
    """Indices of the robots drawn in colour: all up to ``INDIVIDUAL_MAX``, else ``k`` evenly spaced."""
    if n <= INDIVIDUAL_MAX:
        return np.arange(n)
    return np.unique(np.linspace(0, n - 1, k).round().astype(int))


def _lines(ax, curves: Sequence[np.ndarray], colors, lw: float, alpha: float = 1.0, ls: str = "-", zorder: float = 2):
    """Many polylines ((M_i, 2) arrays) as one LineCollection."""
    from matplotlib.collections import LineCollection

    lc = LineCollection([np.asarray(c, dtype=float) for c in curves], colors=colors, linewidths=lw, alpha=alpha,
                        linestyles=ls, zorder=zorder)
    ax.add_collection(lc)
    return lc


def _log_norm(vmin: float, vmax: float):
    from matplotlib.colors import LogNorm

    return LogNorm(vmin=vmin, vmax=vmax)


def _robot_colors(n: int):
    plt = _plt()
    cmap = plt.get_cmap("tab10" if n <= 10 else "turbo")
    return [cmap(i % 10) if n <= 10 else cmap(i / max(1, n - 1)) for i in range(n)]


AXES = "xyz"
"""Axis names, in the order of a position's coordinates."""

View = tuple[int, int]
"""A projection: the coordinates (horizontal, vertical) a panel shows."""


def views(ndim: int) -> list[View]:
    """The panels of a figure: the plane for a 2-D run; top (x-y), side (x-z) and side (z-y) for a 3-D one."""
    return [(0, 1)] if ndim == 2 else [(0, 1), (0, 2), (2, 1)]


def view_figure(grid: OccupancyGrid, width: float = 6.0, dpi: int = 110):
    """A figure with one panel per :func:`views` of ``grid``: ``(fig, [(ax, view), ...])``.

    A 2-D grid gets one figure ``width`` wide, as high as the map's aspect asks. A 3-D grid gets the three projections
    on a 2 x 2 grid whose rows and columns are sized by the map's extents, the top view's
    x shared with the x-z view below it and its y with the z-y view beside it; the fourth
    cell holds the legend (:func:`legend_axes`).
    """
    plt = _plt()
    if grid.ndim == 2:
        lo, hi = grid.bounds
        # as high as the map is for its width (a 100 x 60 m map in a square figure left a band empty), within
        # a fifth and one and a half times the width (a 60 x 8 m map at half of it: bands above and below), plus
        # room for the title, the legend and the labels
        aspect = float(np.clip((hi[1] - lo[1]) / (hi[0] - lo[0]), 0.2, 1.5))
        fig, ax = plt.subplots(figsize=(width, width * aspect * 0.85 + 1.6), dpi=dpi)
        return fig, [(ax, (0, 1))]
    span = _layout_span(grid)
    w = 1.25 * width
    h = w * (span[1] + span[2]) / (span[0] + span[2]) + 1.0  # room for titles and labels (:func:`fit_inside`)
    fig = plt.figure(figsize=(w, h), dpi=dpi)
    gs = fig.add_gridspec(2, 2, width_ratios=[span[0], span[2]], height_ratios=[span[1], span[2]])
    top = fig.add_subplot(gs[0, 0])
    side_x = fig.add_subplot(gs[1, 0], sharex=top)
    side_y = fig.add_subplot(gs[0, 1], sharey=top)
    fig.add_subplot(gs[1, 1], label=_LEGEND).set_axis_off()
    return fig, [(top, (0, 1)), (side_x, (0, 2)), (side_y, (2, 1))]


_LEGEND = "legend cell"


def fit_inside(fig, margin: float = 0.05, rounds: int = 3) -> None:
    """``tight_layout``, then the figure grown by what it draws nearer than ``margin`` (inches) to its edges or past
    them, until nothing is.

    The panels of a 3-D figure keep their aspect, so ``tight_layout`` cannot always make room for the labels: on a
    flat map (50 x 6 x 4 m) the x-z view's "x [m]" fell below the figure and the z-y view's "z [m], drawn x2.5" past
    its right edge, in the PNGs and in every frame of the GIF (which cannot be cropped to its ink).
    """
    for _ in range(rounds):
        fig.tight_layout()
        box = fig.get_tightbbox()  # inches
        w, h = fig.get_size_inches()
        grow = np.array([max(0.0, margin - box.x0) + max(0.0, box.x1 - w + margin),
                         max(0.0, margin - box.y0) + max(0.0, box.y1 - h + margin)])
        if not (grow > 1e-3).any():
            return
        fig.set_size_inches(w + grow[0], h + grow[1])


def fit_height(fig, ax, pad: float = 0.15) -> None:
    """``tight_layout``, then the figure lowered (the width kept) to what ``ax``, held at its aspect, draws.

    A figure taller than the axes needs draws it in the middle of blank bands. The figure is made as high as the
    axes, what is drawn above and below it (title, labels) and ``pad`` (inches, ``tight_layout``'s) at each edge,
    the axes' cell as high as the axes. Not ``tight_layout`` again: it measures an axes held at its aspect only
    roughly, and on a wide map it left the y labels outside the figure.
    """
    fig.tight_layout()
    ax.apply_aspect()
    w, h = fig.get_size_inches()
    cell, drawn = ax.get_position(original=True), ax.get_position()
    if cell.height - drawn.height < 1e-3:
        return  # the axes fills its cell's height: no band above or below it
    ink = fig.get_tightbbox()  # inches
    below = drawn.y0 * h - ink.y0 + pad
    above = ink.y1 - drawn.y1 * h + pad
    height = below + drawn.height * h + above
    fig.set_size_inches(w, height)
    fig.subplots_adjust(bottom=below / height, top=1.0 - above / height)


#: The side views of a 3-D figure are at least this share of the map's larger horizontal extent high: a flatter
#: map's heights are drawn stretched (a map one voxel high got side panels a few pixels thick, their ticks overlapping).
SIDE_SHARE = 0.2


def z_stretch(grid: OccupancyGrid) -> float:
    """How many times a 3-D figure's side views stretch heights (1: drawn to scale; see :data:`SIDE_SHARE`)."""
    lo, hi = grid.bounds
    span = hi - lo
    return max(1.0, SIDE_SHARE * max(span[0], span[1]) / span[2])


def _layout_span(grid: OccupancyGrid) -> np.ndarray:
    """The extents a 3-D figure's panels are sized by: the map's, its height stretched by :func:`z_stretch`."""
    lo, hi = grid.bounds
    span = np.array(hi - lo, dtype=float)
    span[2] *= z_stretch(grid)
    return span


def legend_axes(fig, panels: list):
    """Where a figure's legend (and colour bar) goes: the empty fourth cell of a 3-D layout, else the only panel."""
    return panels[0][0] if len(panels) == 1 else next(a for a in fig.axes if a.get_label() == _LEGEND)


def draw_map(ax, grid: OccupancyGrid, view: View = (0, 1)) -> None:
    """Obstacles in grey on white, world coordinates, equal aspect, projected on ``view``.

    A column of voxels along the axis the view leaves out is shaded by the fraction of it
    that is occupied (all: the 2-D grey; none: white). A map of more than
    :data:`DRAWN_CELLS_MAX` cells along an axis is drawn in blocks of cells, shaded so too.
    """
    a, b = view
    occupied = grid.occupied
    if grid.ndim == 3:
        frac = _occupied_fraction(grid, view)
    else:
        frac = (occupied if a < b else occupied.T).astype(float)
    lo, hi = grid.bounds
    frac, blocks = _block_fraction(frac)
    image = _column_grey(frac)
    top = lo[[a, b]] + grid.resolution * np.array(blocks) * image.shape
    ax.imshow(image.T, origin="lower", extent=(lo[a], top[0], lo[b], top[1]), cmap="gray",
              vmin=0, vmax=1, interpolation="nearest")
    ax.set_xlim(lo[a], hi[a])
    ax.set_ylim(lo[b], hi[b])
    stretch = z_stretch(grid) if grid.ndim == 3 and 2 in view else 1.0
    ax.set_aspect(stretch if b == 2 else 1.0 / stretch)  # display length per metre, vertical over horizontal
    label = {k: f"{AXES[k]} [m]" for k in view}
    if stretch > 1:
        label[2] = f"z [m], drawn x{stretch:.3g}"
    # the z-y view is the right column, narrow on a flat map: its longer z label ends at its right edge, not past
    # the figure's (a GIF's frame cut it to "drawn x2.")
    ax.set_xlabel(label[a], loc="right" if a == 2 and stretch > 1 else "center")
    ax.set_ylabel(label[b])


#: Cells along an axis above which :func:`draw_map` draws a map in blocks of cells, each shaded by the occupied
#: fraction of its cells as a voxel column is: a figure has a few hundred pixels across, and its nearest-neighbour
#: resampling kept some cells and dropped others (a 2000 x 2000 MovingAI map's two walls one cell thick: one drawn,
#: the other not).
DRAWN_CELLS_MAX = 256


def _block_fraction(frac: np.ndarray) -> tuple[np.ndarray, tuple[int, int]]:
    """The occupied fraction ``frac`` in blocks of (k0, k1) cells, k = ceil(cells / :data:`DRAWN_CELLS_MAX`) per
    axis, each the mean of its cells (the last blocks' cells past the map left out). Returns it and (k0, k1)."""
    k = tuple(-(-n // DRAWN_CELLS_MAX) for n in frac.shape)
    if k == (1, 1):
        return frac, (1, 1)
    m = tuple(-(-n // kk) for n, kk in zip(frac.shape, k, strict=True))
    total, count = np.zeros((m[0] * k[0], m[1] * k[1])), np.zeros((m[0] * k[0], m[1] * k[1]))
    total[:frac.shape[0], :frac.shape[1]] = frac
    count[:frac.shape[0], :frac.shape[1]] = 1.0
    block = (m[0], k[0], m[1], k[1])
    return total.reshape(block).sum(axis=(1, 3)) / count.reshape(block).sum(axis=(1, 3)), (k[0], k[1])


def _occupied_fraction(grid: OccupancyGrid, view: View) -> np.ndarray:
    """(cells along view[0], cells along view[1]) the occupied fraction of each voxel column along the axis a 3-D
    grid's ``view`` leaves out."""
    a, b = view
    frac = grid.occupied.mean(axis=3 - a - b)  # rows and columns stay in axis order
    return frac if a < b else frac.T


#: The grey of a voxel column with a share of it occupied that tends to 0 (the lightest grey of an occupied column;
#: empty is white): when the grey went on to white, a wall one voxel thick seen edge-on along a long map (window3d's
#: z-y view: 1 voxel of 24) was drawn at 98 % white, its window and gap invisible.
OCCUPIED_GREY = 0.9


def _column_grey(frac: np.ndarray) -> np.ndarray:
    """The grey of voxel columns occupied by ``frac``: 0.55 when full (as a 2-D obstacle), linearly lighter to
    :data:`OCCUPIED_GREY` as less of it is occupied; 1 (white) when empty."""
    frac = np.asarray(frac, dtype=float)
    return np.where(frac > 0, OCCUPIED_GREY - (OCCUPIED_GREY - 0.55) * frac, 1.0)


def draw_paths(ax, grid: OccupancyGrid, paths_world: Sequence[np.ndarray], goal: np.ndarray | None = None,
               markers: bool = True, lw: float = 1.4, waypoints: Sequence[np.ndarray] | None = None,
               view: View = (0, 1), colorbar=True) -> None:
    """Each robot's path (an (T, d) array in metres) with start (green) and end (blue) markers, projected on ``view``.

    Above ``INDIVIDUAL_MAX`` robots: a density image and a highlighted sample of paths
    (module docstring); waypoints only for the sample; ``colorbar``: the density's colour
    bar below ``ax`` (True), below another axes (an Axes) or none (False).
    """
    n = len(paths_world)
    v = list(view)
    paths_world = [np.asarray(p)[:, v] for p in paths_world]
    if waypoints is not None:
        waypoints = [np.asarray(w)[:, v] for w in waypoints]
    if goal is not None:
        goal = np.asarray(goal)[v]
    if n > INDIVIDUAL_MAX:
        _draw_swarm(ax, grid, paths_world, lw, waypoints, view, colorbar)
    else:
        colors = _robot_colors(n)
        if n:
            _lines(ax, paths_world, colors, lw, alpha=0.9)
        if waypoints is not None:
            for i in range(n):
                w = waypoints[i]
                ax.plot(w[:, 0], w[:, 1], "o", ms=3, mfc="white", mec=colors[i], mew=1.0)
    if markers and n:
        big = n <= INDIVIDUAL_MAX
        ms, mec = (7, "k") if big else (max(1.5, 7 / np.sqrt(n / INDIVIDUAL_MAX)), "none")
        starts = np.array([p[0] for p in paths_world])
        ends = np.array([p[-1] for p in paths_world])
        ax.plot(starts[:, 0], starts[:, 1], "o", ms=ms, color="tab:green", mec=mec, mew=0.6, label="start", zorder=5)
        ax.plot(ends[:, 0], ends[:, 1], "o", ms=ms, color="tab:blue", mec=mec, mew=0.6, label="end", zorder=5)
    if goal is not None:
        # hollow, on top: a robot that ends on the goal cell shows through (a filled star hid its end marker)
        ax.plot(goal[0], goal[1], "*", ms=18, mfc="none", mec="darkgoldenrod", mew=2.0, label="goal", zorder=6)


def _draw_swarm(ax, grid: OccupancyGrid, paths_world: Sequence[np.ndarray], lw: float,
                waypoints: Sequence[np.ndarray] | None, view: View = (0, 1), colorbar=True) -> None:
    """Density of robot-samples per cell (of the projection ``view``; paths already projected) and a
    highlighted sample of paths in colour."""
    n = len(paths_world)
    pts = np.concatenate([np.asarray(p, dtype=float) for p in paths_world])
    a, b = view
    lo, hi = grid.bounds
    x0, x1, y0, y1 = lo[a], hi[a], lo[b], hi[b]
    hist, _, _ = np.histogram2d(pts[:, 0], pts[:, 1], bins=(grid.shape[a], grid.shape[b]), range=((x0, x1), (y0, y1)))
    masked = np.ma.masked_equal(hist.T, 0)
    im = ax.imshow(masked, origin="lower", extent=(x0, x1, y0, y1), cmap="Purples", alpha=0.75,
                   interpolation="nearest", norm=_log_norm(1, max(2.0, float(hist.max()))),
                   zorder=1)
    if grid.ndim == 3:
        # the voxel columns the view sees partly occupied (a block floating or standing, light grey in draw_map)
        # shaded again above the density, which covered them where robots flew over or under them
        frac = _occupied_fraction(grid, view)
        shade = np.zeros((*frac.shape, 4))
        shade[..., :3] = _column_grey(frac)[..., None]
        shade[..., 3] = np.where(frac > 0, 0.85, 0.0)
        ax.imshow(shade.transpose(1, 0, 2), origin="lower", extent=(x0, x1, y0, y1), interpolation="nearest",
                  zorder=2)
    if colorbar is not False:
        cb = ax.figure.colorbar(im, ax=ax if colorbar is True else colorbar, orientation="horizontal", fraction=0.04,
                                pad=0.16, aspect=40)  # below the x label
        cb.set_label(f"samples of the {n} robots per cell" if colorbar is True  # else beside: two lines
                     else f"samples per cell\n({n} robots)")
    pick = highlighted(n)
    colors = _robot_colors(len(pick))
    _lines(ax, [paths_world[i] for i in pick], colors, lw=max(lw, 1.2), zorder=4)
    ax.plot([], [], "-", color=colors[0], lw=1.2, label=f"{len(pick)} of {n} paths")
    if waypoints is not None:
        for c, i in zip(colors, pick):
            w = waypoints[i]
            ax.plot(w[:, 0], w[:, 1], "o", ms=3, mfc="white", mec=c, mew=1.0, zorder=4)


def plot_paths(path: Path, grid: OccupancyGrid, paths_world: Sequence[np.ndarray], goal: np.ndarray | None = None,
               title: str = "", waypoints: Sequence[np.ndarray] | None = None,
               beneath: Sequence[np.ndarray] | None = None, title_size: float | None = None) -> Path:
    """Paths over the map (the paper's Fig. 6 panels); a 3-D run's in three projections (:func:`view_figure`).

    ``beneath``: other paths drawn first as grey dotted lines (the discrete paths under the
    smooth ones).
    """
    fig, panels = view_figure(grid)
    for k, (ax, view) in enumerate(panels):
        draw_map(ax, grid, view)
        if beneath is not None:
            _lines(ax, [np.asarray(p)[:, list(view)] for p in beneath], "0.5", lw=0.8, ls=":")
            if k == 0:
                ax.plot([], [], color="0.5", lw=0.8, ls=":", label="discrete paths")
        draw_paths(ax, grid, paths_world, goal, waypoints=waypoints, view=view,
                   colorbar=(k == 0) and (len(panels) == 1 or legend_axes(fig, panels)))
    size = {} if title_size is None else {"fontsize": title_size}
    if len(panels) == 1:
        # above the map in one row: inside it, the legend covered a long thin map's start
        panels[0][0].legend(loc="lower left", bbox_to_anchor=(0.0, 1.01), ncol=5, fontsize=8, frameon=False,
                            borderaxespad=0.0, markerscale=0.8)
        fig.suptitle(title, **size)
    else:
        handles, labels = panels[0][0].get_legend_handles_labels()
        legend_axes(fig, panels).legend(handles, labels, loc="center", fontsize=8, framealpha=0.9)
        fig.suptitle(title, **size)
    fig.tight_layout() if len(panels) == 1 else fit_inside(fig)
    return save_figure(fig, path, dpi=110)


def _whole_steps(ax) -> None:
    """Ticks at whole MRF steps only (a plan of 3 steps had ticks at 0.5, 1.5 and 2.5; one of 0 steps at -0.04)."""
    from matplotlib.ticker import MaxNLocator

    ax.xaxis.set_major_locator(MaxNLocator(integer=True, min_n_ticks=1))  # 2 (the default): fractions on one step


def plot_energy(path: Path, energies: dict[str, np.ndarray], title: str = "Swarm energy") -> Path:
    """Swarm energy per MRF step, one line per series (the paper's Fig. 8a)."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6, 4), dpi=110)
    for name, e in energies.items():
        ax.plot(np.arange(len(e)), e, "-o", ms=3, label=name)
    ax.set_xlabel("MRF step")
    _whole_steps(ax)
    values = np.concatenate([np.asarray(e, dtype=float).ravel() for e in energies.values()] or [np.zeros(0)])
    values = values[np.isfinite(values)]
    # the goal potential is exponential in the distance: a big swarm's energy falls by orders of magnitude, and on
    # a linear axis its second half was a flat line at 0 (big-swarm tour)
    log_axis = values.size > 0 and values.min() > 0 and values.max() > 100 * values.min()
    if log_axis:
        ax.set_yscale("log")
    ax.set_ylabel("swarm energy" + (" (log scale)" if log_axis else ""))
    ax.set_title(title)
    ax.grid(alpha=0.3)
    if len(energies) > 1:
        ax.legend(fontsize=8)
    fig.tight_layout()
    return save_figure(fig, path, dpi=110)


def plot_distances(path: Path, t: np.ndarray, min_d: np.ndarray, mean_d: np.ndarray, safety: float | None = None,
                   xlabel: str = "time [s]", mean_pairs: int | None = None, ylabel: str = "distance [m]",
                   safety_label: str | None = None, title: str | None = None) -> Path:
    """Minimum and average inter-robot distance over time (the paper's Fig. 7c).

    ``t``: times (s), or MRF steps as an integer array (then ticks at whole steps only).
    ``title``: above the legend (a run's two distance figures said neither which stage they show).

    ``mean_pairs``: when the average is over a sample of pairs, how many (said in the legend).
    ``ylabel``: which distance (the downwash-scaled one of a 3-D run says so).
    ``safety``: a dashed line at that distance, named ``safety_label`` formatted with it (default: "safety distance
    {:g} m").
    """
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7, 3.5), dpi=110)
    marker = "o" if len(t) == 1 else None  # a plan of 0 steps: one point, which a line alone does not draw
    average = "average distance" + (f" ({mean_pairs:,} random pairs)" if mean_pairs else "")
    ax.plot(t, mean_d, marker=marker, label=average)
    ax.plot(t, min_d, marker=marker, label="minimum distance")
    if safety is not None:
        # beneath the curves: a minimum on the line stays visible
        ax.axhline(safety, color="r", ls="--", lw=1, zorder=1,
                   label=(safety_label or "safety distance {:g} m").format(safety))
    ax.set_xlabel(xlabel)
    if np.issubdtype(np.asarray(t).dtype, np.integer):  # MRF steps
        _whole_steps(ax)
    ax.set_ylabel(ylabel)
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3)
    # above the axes, in one row: inside them it covered the safety line or a curve (the arena's, at the start)
    ax.legend(fontsize=8, loc="lower left", bbox_to_anchor=(0.0, 1.01), ncol=3, frameon=False, borderaxespad=0.0)
    if title:
        fig.suptitle(title, fontsize=10)
        fig.tight_layout(rect=(0.0, 0.0, 1.0, 0.97))
    else:
        fig.tight_layout()
    return save_figure(fig, path, dpi=110)


def plot_xy(path: Path, t: np.ndarray, positions: np.ndarray) -> Path:
    """Each robot's x and y (and z in 3-D) over time (the paper's Fig. 7a); ``positions`` (S, N, d).

    Above ``INDIVIDUAL_MAX`` robots, all faint and a highlighted sample in colour.
    """
    plt = _plt()
    d = positions.shape[-1]
    fig, axes = plt.subplots(d, 1, figsize=(7, 2.5 * d), dpi=110, sharex=True)
    for k in range(d):
        _time_lines(axes[k], t, positions[..., k])
        axes[k].set_ylabel(f"{AXES[k]} [m]")
    axes[-1].set_xlabel("time [s]")
    for ax in axes:
        ax.grid(alpha=0.3)
    axes[0].set_title(f"each robot's {', '.join(AXES[:d])} over time", fontsize=10)
    _robot_legend(axes[0], positions.shape[1])
    fig.tight_layout()
    return save_figure(fig, path, dpi=110)


#: Robots up to this many get a legend of their colours in the plots over time (more: the colours as in the
#: trajectory figure, which draws the same robots in the same colours).
LEGEND_ROBOTS = 10


def _robot_legend(ax, n: int) -> None:
    """A legend naming each robot's colour (:func:`_time_lines`' colours), right of ``ax``, for a few robots."""
    if n > LEGEND_ROBOTS:
        return
    from matplotlib.lines import Line2D

    handles = [Line2D([], [], color=c, lw=1.5) for c in _robot_colors(n)]
    ax.legend(handles, [f"robot {i}" for i in range(n)], fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0),
              borderaxespad=0.0)


def _time_lines(ax, t: np.ndarray, values: np.ndarray, lw: float = 1.2) -> None:
    """One curve per column of ``values`` (S, N) over ``t``, as LineCollections."""
    n = values.shape[1]
    curves = [np.stack([t, values[:, i]], axis=1) for i in range(n)]
    pick = highlighted(n)
    if n > INDIVIDUAL_MAX:  # the faint background needs no more points than pixels
        every = max(1, len(t) // _FAINT_POINTS)
        _lines(ax, [np.stack([t[::every], values[::every, i]], axis=1) for i in range(n)], "0.5", lw=0.3, alpha=0.3)
    _lines(ax, [curves[i] for i in pick], _robot_colors(len(pick)) if n > INDIVIDUAL_MAX else _robot_colors(n), lw)
    ax.autoscale_view()


def plot_tracking(path: Path, t: np.ndarray, errors: np.ndarray, end: float | None = None) -> Path:
    """Tracking error of each simulated robot over time; ``errors`` (S, N) metres; ``end``: the planned flight's end
    (s), marked, where the simulation hovers on past it."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7, 3.5), dpi=110)
    _time_lines(ax, t, errors * 100, lw=1.0)
    if end is not None and len(t) and t[-1] > end:
        ax.axvline(end, color="0.4", ls="--", lw=0.8)
        ax.annotate("end of the plan (hovering after)", (end, 0.97), xycoords=("data", "axes fraction"), fontsize=7,
                    ha="right", va="top", color="0.3", xytext=(-3, 0), textcoords="offset points")
    if errors.shape[1] > INDIVIDUAL_MAX:
        ax.plot(t, errors.max(axis=1) * 100, color="k", lw=1.0, label="maximum over robots")
        ax.legend(fontsize=8)
    else:
        _robot_legend(ax, errors.shape[1])
    ax.set_title("tracking error of each robot in the simulated flight", fontsize=10)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("tracking error [cm]")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return save_figure(fig, path, dpi=110)


def animate(path: Path, grid: OccupancyGrid, t: np.ndarray, positions: np.ndarray, goal: np.ndarray | None = None,
            fps: int = 10, trail_s: float = 3.0) -> Path:
    """A GIF of the swarm flying: ``positions`` (S, N, d) at times ``t`` (one frame each); a 3-D
    run's in the three projections of :func:`view_figure`."""
    plt = _plt()
    from matplotlib.animation import FuncAnimation, PillowWriter

    fig, panels = view_figure(grid, width=5.0, dpi=80)
    n = positions.shape[1]
    colors = _robot_colors(n)
    size = 30 if n <= INDIVIDUAL_MAX else max(2.0, 30 * INDIVIDUAL_MAX / n)
    drawn = []
    for ax, view in panels:
        v = list(view)
        draw_map(ax, grid, view)
        if goal is not None:
            ax.plot(goal[v[0]], goal[v[1]], "*", ms=16, mfc="none", mec="darkgoldenrod", mew=2.0, zorder=6)
        p = positions[..., v]
        dots = ax.scatter(p[0, :, 0], p[0, :, 1], s=size, c=colors,
                          edgecolors="k" if n <= INDIVIDUAL_MAX else "none", zorder=5)
        trails = _lines(ax, [p[:1, i] for i in range(n)], colors, lw=1.0 if n <= INDIVIDUAL_MAX else 0.4, alpha=0.7)
        drawn.append((p, dots, trails))
    title = panels[0][0].set_title("") if len(panels) == 1 else fig.suptitle("")
    if len(panels) > 1:
        fit_inside(fig)
    else:
        # view_figure's height has room for a legend, which the animation has not: the map, held at its aspect,
        # sat in the middle, a blank band of 0.7 inch above the title (57 px of a 400 px wide GIF) and one below
        title.set_text(f"t = {t[-1]:.1f} s")
        fit_height(fig, panels[0][0])
    span = max(1, int(round(trail_s * fps)))

    def frame(k: int):
        artists = [title]
        for p, dots, trails in drawn:
            dots.set_offsets(p[k])
            trails.set_segments(list(p[max(0, k - span):k + 1].transpose(1, 0, 2)))
            artists += [dots, trails]
        title.set_text(f"t = {t[k]:.1f} s")
        return artists

    anim = FuncAnimation(fig, frame, frames=len(t), blit=False)
    anim.save(str(path), writer=PillowWriter(fps=fps))
    plt.close(fig)
    return Path(path)


# --- small helpers for multi-panel figures (used by mrfswarm.figures) -------------------------

#: Font sizes of the paper figures: readable when a panel is a quarter of a page wide.
PAPER_RC = {
    "font.size": 10,
    "axes.titlesize": 10.5,
    "axes.labelsize": 10,
    "xtick.labelsize": 9,
    "ytick.labelsize": 9,
    "legend.fontsize": 8.5,
    "figure.titlesize": 12.5,
}


def paper_style():
    """A context manager applying :data:`PAPER_RC` (``with plots.paper_style(): ...``)."""
    return _plt().rc_context(PAPER_RC)


def panel_title(ax, letter: str, text: str, **kw) -> None:
    """A panel title in the paper's style: "(a) text"."""
    ax.set_title(f"({letter}) {text}", **kw)


def plain_log_ticks(axis) -> None:
    """Plain numbers on a log ``axis`` ("4", not "4 x 10^0"), its minor ticks labelled at 2, 3 and 5 times a power of
    ten only (every one of them labelled stacked 60, 70, 80, 90 under 100: Fig. 8b's time per step)."""
    from matplotlib.ticker import FuncFormatter

    def minor(v: float, _) -> str:
        return f"{v:g}" if v > 0 and round(v / 10 ** np.floor(np.log10(v))) in (2, 3, 5) else ""

    axis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    axis.set_minor_formatter(FuncFormatter(minor))


def draw_graph(ax, points: np.ndarray, edges: np.ndarray, labels: bool = True, node_size: float = 260,
               color: str = "tab:blue", edge_color: str = "0.35") -> None:
    """Robots as numbered nodes (1-based, as the paper's figures) and their undirected edges."""
    pts = np.asarray(points, dtype=float)
    for a, b in np.asarray(edges).reshape(-1, 2):
        ax.plot(pts[[a, b], 0], pts[[a, b], 1], "-", color=edge_color, lw=1.6, zorder=2)
    ax.scatter(pts[:, 0], pts[:, 1], s=node_size, c=color, edgecolors="k", linewidths=0.8, zorder=3)
    if labels:
        for i, p in enumerate(pts):
            ax.text(p[0], p[1], str(i + 1), ha="center", va="center", color="white", fontsize=9,
                    fontweight="bold", zorder=4)


def draw_field(ax, field: np.ndarray, extent: tuple[float, float, float, float], label: str = "",
               cmap: str = "viridis", contours: int = 0, **imshow_kw):
    """A scalar field indexed ``[ix, iy]`` as an image in world coordinates, with a colour bar.

    ``contours`` > 0 overlays that many thin contour lines. Returns the image.
    """
    im = ax.imshow(np.asarray(field).T, origin="lower", extent=extent, cmap=cmap, interpolation="nearest",
                   **imshow_kw)
    if contours:
        x0, x1, y0, y1 = extent
        W, H = np.asarray(field).shape
        xs = np.linspace(x0, x1, W, endpoint=False) + (x1 - x0) / (2 * W)
        ys = np.linspace(y0, y1, H, endpoint=False) + (y1 - y0) / (2 * H)
        ax.contour(xs, ys, np.asarray(field).T, levels=contours, colors="w", linewidths=0.5, alpha=0.6)
    cb = ax.figure.colorbar(im, ax=ax, fraction=0.046, pad=0.03)
    if label:
        cb.set_label(label)
    ax.set_aspect("equal")
    return im


def obstacle_edges(grid: OccupancyGrid) -> np.ndarray:
    """The cell faces between an occupied cell and a free one (or the map's edge) of a 2-D grid.

    Returns world segments, shape (n, 2, 2): n faces, each its two ends (x, y).
    """
    occ = np.asarray(grid.occupied, dtype=bool)
    x_faces = np.argwhere(np.diff(np.pad(occ, ((1, 1), (0, 0))).astype(np.int8), axis=0) != 0)  # face i - 1/2
    y_faces = np.argwhere(np.diff(np.pad(occ, ((0, 0), (1, 1))).astype(np.int8), axis=1) != 0)
    segs = np.concatenate([
        np.stack([x_faces - [0.5, 0.5], x_faces + [-0.5, 0.5]], axis=1),
        np.stack([y_faces - [0.5, 0.5], y_faces + [0.5, -0.5]], axis=1),
    ]).astype(float)
    return np.asarray(grid.origin[:2], dtype=float) + grid.resolution * segs


def outline_obstacles(ax, grid: OccupancyGrid, color: str = "k", linewidth: float = 1.5) -> None:
    """Outline a 2-D grid's occupied cells on ``ax``: over a field, where :func:`draw_map`'s grey would hide it."""
    from matplotlib.collections import LineCollection

    ax.add_collection(LineCollection(list(obstacle_edges(grid)), colors=color, linewidths=linewidth, zorder=4,
                                     capstyle="projecting"))


def save_figure(fig, path: Path, dpi: int = 100) -> Path:
    """Save a figure as a PNG (limited dpi) and close it.

    Not PIL's ``optimize``: it saved 3 % of the bytes (the forest's seven figures 357 -> 347 kB)
    and took a third of the time of writing a small run's outputs (0.64-0.75 s -> 0.97-1.47 s).
    """
    plt = _plt()
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return Path(path)
