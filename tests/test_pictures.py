"""A run's pictures in 2-D and 3-D: projections of voxel maps, the interactive HTML view, the animation.

The 3-D data is a flight built without the planner (:mod:`support.flight3d`): a voxel map with a wall and a
window, discrete paths on voxel centres and their min-snap trajectories.
"""

from __future__ import annotations

import re

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from mrfswarm import plots
from mrfswarm.figures import interactive
from mrfswarm.maps import OccupancyGrid
from support.flight3d import window_flight
from support.repository import EXPERIMENTS

pytest.importorskip("plotly")


@pytest.fixture(scope="module")
def flight():
    return window_flight(8)


def exposed_faces(occ: np.ndarray) -> dict:
    """Brute force: every exposed unit face as (axis, side) -> set of (plane, the other two corner indices)."""
    out = {}
    W, H, D = occ.shape
    for a in range(3):
        for side in (-1, 1):
            faces = set()
            for idx in np.argwhere(occ):
                nb = idx.copy()
                nb[a] += side
                inside = all(0 <= nb[k] < occ.shape[k] for k in range(3))
                if not inside or not occ[tuple(nb)]:
                    corner = idx.copy()
                    corner[a] += side > 0
                    faces.add(tuple(int(v) for v in corner))
            out[(a, side)] = faces
    return out


def raster(lo: np.ndarray, hi: np.ndarray, normal: np.ndarray) -> tuple[dict, int]:
    """The unit faces the rectangles cover, per (axis, side), and how many unit faces they cover in all."""
    out: dict = {}
    total = 0
    for l, h, n in zip(lo, hi, normal):
        a, side = abs(int(n)) - 1, int(np.sign(n))
        ranges = [range(l[k], h[k]) if k != a else [l[k]] for k in range(3)]
        cells = {(x, y, z) for x in ranges[0] for y in ranges[1] for z in ranges[2]}
        total += len(cells)
        out.setdefault((a, side), set()).update(cells)
    return out, total


@settings(max_examples=60, deadline=None)
@given(arrays(bool, st.tuples(st.integers(1, 6), st.integers(1, 6), st.integers(1, 5))))
def test_voxel_faces_cover_exactly_the_exposed_faces_once(occ):
    lo, hi, normal = interactive.voxel_faces(occ)
    expected = exposed_faces(occ)
    covered, total = raster(lo, hi, normal)
    assert {k: v for k, v in covered.items() if v} == {k: v for k, v in expected.items() if v}
    assert total == sum(len(v) for v in expected.values())  # no face twice: the rectangles do not overlap
    assert np.all(lo <= hi) and np.all((hi - lo)[np.arange(len(lo)), np.abs(normal) - 1] == 0)


def test_a_box_of_voxels_is_six_rectangles_and_the_map_surface_stays_small(flight):
    occ = np.zeros((20, 10, 6), dtype=bool)
    occ[3:11, 2:9, 1:5] = True
    lo, hi, normal = interactive.voxel_faces(occ)
    assert len(lo) == 6 and sorted(normal.tolist()) == [-3, -2, -1, 1, 2, 3]
    assert interactive.voxel_faces(np.zeros((3, 3, 3), dtype=bool))[0].shape == (0, 3)
    with pytest.raises(ValueError, match=r"\(W, H, D\)"):
        interactive.voxel_faces(np.zeros((3, 3), dtype=bool))
    # the window flight's map: a wall with a window (16 faces: 4 outer, 2 x 4 around the hole... merged) and a pillar
    v, t = interactive.face_mesh(flight.grid)
    assert len(t) == 2 * len(v) // 4 and len(v) // 4 <= 30


def test_face_mesh_is_the_voxel_surface_in_world_coordinates(flight):
    grid = flight.grid
    v, t = interactive.face_mesh(grid)
    corners = (v - np.asarray(grid.origin)) / grid.resolution + 0.5  # voxel-corner coordinates
    assert np.allclose(corners, np.rint(corners))
    tri = v[t]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1).sum()
    n_faces = sum(len(f) for f in exposed_faces(grid.occupied).values())
    assert area == pytest.approx(n_faces * grid.resolution**2)
    lo, hi = grid.bounds
    assert np.all(v >= lo - 1e-12) and np.all(v <= hi + 1e-12)


def test_scene_holds_the_map_the_paths_and_the_trajectories(flight):
    t = np.linspace(0.0, flight.trajectories[0].duration, 101)
    pos = flight.positions(t)
    fig = interactive.scene(flight.grid, flight.discrete, pos, t, flight.goal, title="window")
    traces = {tr.name: tr for tr in fig.data}
    assert set(traces) == {"obstacles", "map bounds", "discrete paths", "trajectories", "start", "end", "goal"}
    N = pos.shape[1]
    traj = np.stack([np.asarray(traces["trajectories"][k], dtype=float) for k in "xyz"], axis=1)
    assert traj.shape == (N * (len(t) + 1), 3)
    assert np.array_equal(traj.reshape(N, len(t) + 1, 3)[:, :-1], pos.transpose(1, 0, 2))  # robot by robot
    assert np.isnan(traj.reshape(N, len(t) + 1, 3)[:, -1]).all()  # a gap between robots
    disc = np.stack([np.asarray(traces["discrete paths"][k], dtype=float) for k in "xyz"], axis=1)
    assert np.array_equal(disc.reshape(N, -1, 3)[:, :-1], flight.discrete.transpose(1, 0, 2))
    assert np.array_equal(np.stack([traces["end"][k] for k in "xyz"], axis=1), pos[-1])
    assert list(traces["goal"].x) == [flight.goal[0]]
    assert fig.layout.scene.aspectmode == "data"


def test_many_samples_are_thinned_to_the_budget(flight, monkeypatch):
    monkeypatch.setattr(interactive, "MAX_SAMPLES", 8 * 50)
    t = np.linspace(0.0, flight.trajectories[0].duration, 1001)
    pos = flight.positions(t)
    fig = interactive.scene(flight.grid, flight.discrete, pos, t)
    traj = next(tr for tr in fig.data if tr.name == "trajectories")
    kept = len(traj.x) // 8 - 1
    assert kept <= 51 and np.array_equal(np.asarray(traj.x[kept - 1], dtype=float), pos[-1, 0, 0])  # the end kept


def test_a_2d_run_is_one_layer_at_its_altitude():
    occ = np.zeros((10, 6), dtype=bool)
    occ[4:6, 1:5] = True
    grid = OccupancyGrid.from_occupied(occ)
    paths = np.stack([np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 1.0]])] * 2, axis=1) + [0.0, 3.0] * np.arange(2)[:, None]
    fig = interactive.scene(grid, paths, altitude=1.5)
    mesh = next(tr for tr in fig.data if tr.name == "obstacles")
    assert set(np.round(np.asarray(mesh.z, dtype=float), 9)) == {1.0, 2.0}  # one cell around 1.5 m
    disc = next(tr for tr in fig.data if tr.name == "discrete paths")
    z = np.asarray(disc.z, dtype=float)
    assert np.all((z == 1.5) | np.isnan(z))


def test_html_is_self_contained_and_small(flight, tmp_path):
    t = np.linspace(0.0, flight.trajectories[0].duration, 157)
    path = interactive.write_scene(tmp_path / "scene.html", flight.grid, flight.discrete, flight.positions(t), t,
                                   flight.goal, title="window")
    html = path.read_text()
    assert not re.search(r"<script[^>]*\bsrc=", html)  # plotly.js inlined, nothing fetched
    assert "Plotly.newPlot" in html and "trajectories" in html
    assert path.stat().st_size < 6_000_000  # plotly.js (~4.7 MB) and the scene
    # a bigger map with many boxes: the surface grows with the obstacles, not the volume
    rng = np.random.default_rng(0)
    occ = np.zeros((128, 64, 16), dtype=bool)
    for x, y in rng.integers(0, 60, size=(40, 2)):
        occ[2 * x:2 * x + 4, y:y + 3, :rng.integers(4, 16)] = True
    big = OccupancyGrid.from_occupied(occ)
    size = interactive.write_scene(tmp_path / "big.html", big, np.zeros((2, 1, 3))).stat().st_size
    assert size - path.stat().st_size < 1_000_000


# --- matplotlib projections ---------------------------------------------------------------------


def test_views_and_layout(flight):
    assert plots.views(2) == [(0, 1)] and plots.views(3) == [(0, 1), (0, 2), (2, 1)]
    fig, panels = plots.view_figure(flight.grid)
    assert [v for _, v in panels] == plots.views(3) and len(fig.axes) == 4
    top, side_x, side_y = (ax for ax, _ in panels)
    assert side_x.get_shared_x_axes().joined(top, side_x) and side_y.get_shared_y_axes().joined(top, side_y)
    plots._plt().close(fig)


@pytest.mark.parametrize("view", [(0, 1), (0, 2), (2, 1)])
def test_projected_map_shades_by_the_occupied_fraction(flight, view):
    plt = plots._plt()
    fig, ax = plt.subplots()
    plots.draw_map(ax, flight.grid, view)
    image = np.asarray(ax.images[0].get_array())  # rows: the view's vertical axis
    occ = flight.grid.occupied
    drop = 3 - sum(view)
    frac = occ.mean(axis=drop)
    frac = frac if view[0] < view[1] else frac.T
    assert np.allclose(image, np.where(frac.T > 0, plots.OCCUPIED_GREY - (plots.OCCUPIED_GREY - 0.55) * frac.T, 1.0))
    assert plots.OCCUPIED_GREY <= 0.9  # an occupied column is seen however little of it is occupied
    assert np.all((image < 1.0) == (frac.T > 0))  # a column with any occupied voxel is seen
    lo, hi = flight.grid.bounds
    assert ax.images[0].get_extent() == [lo[view[0]], hi[view[0]], lo[view[1]], hi[view[1]]]
    assert ax.get_xlabel() == f"{'xyz'[view[0]]} [m]" and ax.get_ylabel() == f"{'xyz'[view[1]]} [m]"
    plt.close(fig)


def test_a_flat_voxel_map_gets_readable_side_views():
    """A map one voxel high got side panels a few pixels thick with overlapping ticks: its heights are drawn
    stretched (and say so), so that each side view is at least SIDE_SHARE of the larger horizontal extent; a map
    tall enough is drawn to scale."""
    plt = plots._plt()
    flat = OccupancyGrid.from_occupied(np.zeros((32, 16, 1), dtype=bool))
    assert plots.z_stretch(flat) == pytest.approx(plots.SIDE_SHARE * 32)
    fig, panels = plots.view_figure(flat)
    for ax, view in panels:
        plots.draw_map(ax, flat, view)
    fig.canvas.draw()
    top, side_x, side_y = (ax.get_window_extent() for ax, _ in panels)
    assert side_x.height >= 0.9 * plots.SIDE_SHARE * top.width  # the x-z view: z against x
    assert side_y.width >= 0.9 * plots.SIDE_SHARE * top.width
    assert side_x.width == pytest.approx(top.width, rel=0.02) and side_y.height == pytest.approx(top.height, rel=0.02)
    assert "drawn x6.4" in panels[1][0].get_ylabel() and "drawn x6.4" in panels[2][0].get_xlabel()
    assert panels[0][0].get_xlabel() == "x [m]" and panels[0][0].get_aspect() == 1.0
    plt.close(fig)
    tall = OccupancyGrid.from_occupied(np.zeros((32, 16, 8), dtype=bool))
    assert plots.z_stretch(tall) == 1.0
    fig, panels = plots.view_figure(tall)
    for ax, view in panels:
        plots.draw_map(ax, tall, view)
        assert ax.get_aspect() == 1.0 and "drawn" not in ax.get_xlabel() + ax.get_ylabel()
    plt.close(fig)


def test_2d_map_is_the_plane_as_before():
    plt = plots._plt()
    occ = np.zeros((7, 4), dtype=bool)
    occ[2:4, 1] = True
    grid = OccupancyGrid.from_occupied(occ, 0.5, (1.0, -1.0))
    fig, ax = plt.subplots()
    plots.draw_map(ax, grid)
    assert np.array_equal(np.asarray(ax.images[0].get_array()), np.where(occ, 0.55, 1.0).T)
    assert tuple(ax.images[0].get_extent()) == grid.extent
    plt.close(fig)


def test_3d_figures_are_written(flight, tmp_path):
    n = flight.discrete.shape[1]
    t = np.linspace(0.0, flight.trajectories[0].duration, 60)
    pos = flight.positions(t)
    plots.plot_paths(tmp_path / "p.png", flight.grid, [pos[:, i] for i in range(n)], flight.goal, "smoothed",
                     beneath=[flight.discrete[:, i] for i in range(n)])
    plots.plot_xy(tmp_path / "xyz.png", t, pos)
    from PIL import Image

    w, h = Image.open(tmp_path / "p.png").size
    assert w > h > 0.5 * w  # the three views of a 16 x 8 x 4 m map
    w, h = Image.open(tmp_path / "xyz.png").size
    assert h > w  # x, y and z over time: three rows


def test_3d_animation_frames(flight, tmp_path):
    from PIL import Image

    t = np.linspace(0.0, flight.trajectories[0].duration, 6)
    pos = flight.positions(t)
    plots.animate(tmp_path / "a.gif", flight.grid, t, pos, flight.goal, fps=5)
    gif = Image.open(tmp_path / "a.gif")
    assert gif.n_frames == len(t)
    first = np.asarray(gif.convert("RGB"))
    gif.seek(len(t) - 1)
    last = np.asarray(gif.convert("RGB"))
    assert (first != last).any(axis=-1).sum() > 200  # the robots moved in the pictures


def test_a_swarms_legend_and_colour_bar_go_to_the_fourth_cell(flight):
    """Above INDIVIDUAL_MAX robots the density's colour bar is drawn beside the legend cell, and the legend cell is
    still found after it (the colour bar is the figure's last axes)."""
    rng = np.random.default_rng(1)
    n = plots.INDIVIDUAL_MAX + 5
    lo, hi = flight.grid.bounds
    paths = [lo + (hi - lo) * rng.random((6, 3)) for _ in range(n)]
    fig, panels = plots.view_figure(flight.grid)
    cell = plots.legend_axes(fig, panels)
    plots.draw_paths(panels[0][0], flight.grid, paths, view=(0, 1), colorbar=cell)
    assert len(fig.axes) == 5 and plots.legend_axes(fig, panels) is cell and fig.axes[-1] is not cell
    assert "40 robots" not in fig.axes[-1].get_xlabel() and f"({n} robots)" in fig.axes[-1].get_xlabel()
    plots._plt().close(fig)


@pytest.mark.parametrize("view", [(0, 1), (0, 2), (2, 1)])
def test_a_swarms_density_leaves_partly_occupied_columns_visible(view):
    """Above INDIVIDUAL_MAX robots the density image (drawn over the map) hid a block floating or standing in a
    voxel map where robots flew over or under it: those columns are shaded again above the density, the others
    left clear."""
    plt = plots._plt()
    occ = np.zeros((12, 8, 6), dtype=bool)
    occ[5:7, 3:5, 0:2] = True  # a block standing on the floor, a third of the height
    grid = OccupancyGrid.from_occupied(occ)
    rng = np.random.default_rng(0)
    n = plots.INDIVIDUAL_MAX + 10
    lo, hi = grid.bounds
    paths = [np.column_stack([np.linspace(lo[0], hi[0], 40), np.full(40, rng.uniform(lo[1], hi[1])),
                              np.full(40, rng.uniform(3.0, hi[2]))]) for _ in range(n)]  # over the block
    fig, ax = plt.subplots()
    plots.draw_map(ax, grid, view)
    plots.draw_paths(ax, grid, paths, view=view, colorbar=False)
    density = next(im for im in ax.images if im.get_zorder() == 1)
    shade = next(im for im in ax.images if im.get_zorder() == 2)  # above the density, below the paths
    frac = occ.mean(axis=3 - sum(view))
    frac = frac if view[0] < view[1] else frac.T
    alpha = np.asarray(shade.get_array())[..., 3].T  # back to (view[0], view[1]) cells
    assert np.array_equal(alpha > 0, frac > 0)
    covered = ~np.ma.getmaskarray(density.get_array()).T
    # seen from above, the robots that flew over the block cover its columns with density
    assert np.any(covered & (frac > 0)) == (view == (0, 1))
    plt.close(fig)


@pytest.mark.parametrize("n", [3, plots.LEGEND_ROBOTS + 1])
def test_plots_over_time_name_the_robots_colours(tmp_path, n, monkeypatch):
    """robot_xy.png and tracking_error.png had no title and no legend: which curve is which robot could not be
    told. A few robots get a legend of their colours (more: the trajectory figure's colours), both a title."""
    saved = []
    monkeypatch.setattr(plots, "save_figure", lambda fig, path, dpi=110: saved.append(fig) or path)
    t = np.linspace(0.0, 2.0, 21)
    plots.plot_xy(tmp_path / "xy.png", t, np.random.default_rng(0).normal(size=(21, n, 2)))
    plots.plot_tracking(tmp_path / "e.png", t, np.abs(np.random.default_rng(1).normal(size=(21, n))) / 100)
    for fig in saved:
        ax = fig.axes[0]
        assert ax.get_title()
        legend = ax.get_legend()
        if n <= plots.LEGEND_ROBOTS:
            assert [x.get_text() for x in legend.get_texts()] == [f"robot {i}" for i in range(n)]
            colors = [h.get_color() for h in legend.legend_handles]
            assert colors == list(plots._robot_colors(n))
        else:
            assert legend is None
        plots._plt().close(fig)


@pytest.mark.parametrize("d", [2, 3])
def test_the_discrete_paths_beneath_are_in_the_legend(tmp_path, monkeypatch, flight, d):
    """trajectories.png draws the discrete paths dotted under the smooth ones; its legend did not say what they are."""
    saved = []
    monkeypatch.setattr(plots, "save_figure", lambda fig, path, dpi=110: saved.append(fig) or path)
    grid = flight.grid if d == 3 else OccupancyGrid.from_occupied(np.zeros((10, 8), dtype=bool))
    paths = [np.array([[1.0, 1.0, 1.0], [5.0, 3.0, 1.0]])[:, :d], np.array([[1.0, 5.0, 2.0], [6.0, 6.0, 2.0]])[:, :d]]
    for beneath in (paths, None):
        plots.plot_paths(tmp_path / "p.png", grid, paths, None, "t", beneath=beneath)
        texts = [t.get_text() for ax in saved[-1].axes if ax.get_legend() for t in ax.get_legend().get_texts()]
        assert ("discrete paths" in texts) is (beneath is not None)
        plots._plt().close(saved[-1])


def test_a_wide_2d_map_gets_a_figure_as_wide():
    """A 100 x 60 m map was drawn in a square figure, a band of it empty above and below the map."""
    wide = OccupancyGrid.from_occupied(np.zeros((100, 60), dtype=bool))
    square = OccupancyGrid.from_occupied(np.zeros((40, 40), dtype=bool))
    ratios = {}
    for name, grid in (("wide", wide), ("square", square)):
        fig, _ = plots.view_figure(grid)
        w, h = fig.get_size_inches()
        ratios[name] = h / w
        plots._plt().close(fig)
    assert ratios["wide"] < 0.8 < 1.0 < ratios["square"] < 1.2


def test_a_long_thin_maps_legend_covers_no_robot(tmp_path, monkeypatch):
    """A 60 x 8 m map's legend sat inside the map, over its start room (upper left), and its figure was half empty
    above and below the map: the legend is above the map now, and the figure about as high as the map asks."""
    saved = []
    monkeypatch.setattr(plots, "save_figure", lambda fig, path, dpi=110: saved.append(fig) or path)
    grid = OccupancyGrid.from_occupied(np.zeros((60, 8), dtype=bool))
    paths = [np.array([[2.0, y], [55.0, 4.0]]) for y in (2.0, 4.0, 6.0)]
    plots.plot_paths(tmp_path / "p.png", grid, paths, np.array([55.0, 4.0]), "thin")
    fig = saved[-1]
    ax = fig.axes[0]
    fig.canvas.draw()
    box = ax.get_legend().get_window_extent()
    assert box.y0 >= ax.get_window_extent().y1  # above the map
    assert fig._suptitle.get_text() == "thin" and fig._suptitle.get_window_extent().y0 >= box.y1
    w, h = fig.get_size_inches()
    assert h / w < 0.5
    plots._plt().close(fig)


def test_the_discrete_distances_show_the_one_cell_line(tmp_path, monkeypatch):
    """The discrete plan keeps its robots on distinct cells: its distance figure draws one cell (the least it can
    hold) as the flight's figure draws the safety distance."""
    from mrfswarm import outputs
    from mrfswarm.config import load_config
    from mrfswarm.pipeline import plan

    calls = []
    real = plots.plot_distances
    monkeypatch.setattr(plots, "plot_distances", lambda *a, **kw: calls.append(kw) or real(*a, **kw))
    toml = tmp_path / "small.toml"
    rows = ", ".join(['"' + "." * 10 + '"'] * 5)  # 5 x 2.5 m at 0.5 m
    toml.write_text(f"""[scenario]
goal = [4.5, 1.0]
map = {{ kind = "ascii", resolution = 0.5, rows = [{rows}] }}
start = {{ positions = [[0.5, 0.5], [0.5, 1.0], [1.0, 0.5], [1.0, 1.0]] }}
""")
    cfg = load_config(toml, overrides=["smoothing.enabled=false", "simulation.enabled=false"])
    outputs.write_discrete_outputs(plan(cfg, progress=False), tmp_path)
    (kw,) = calls
    assert kw["safety"] == 0.5 and kw["safety_label"].format(kw["safety"]) == "one cell (0.5 m): the least"


def test_a_runs_energy_figure_names_its_mrf_method(tmp_path, monkeypatch):
    """A run's swarm_energy.png, one line and so no legend, was titled "Swarm energy": it did not say which MRF
    method made it (a tour comparing bp's run with icm's)."""
    from mrfswarm import outputs
    from mrfswarm.config import load_config
    from mrfswarm.pipeline import plan

    titles = []
    real = plots.plot_energy
    monkeypatch.setattr(plots, "plot_energy",
                        lambda path, e, **kw: titles.append(kw.get("title")) or real(path, e, **kw))
    cfg = load_config(EXPERIMENTS / "free5.toml",
                      overrides=["mrf.method=bp", "smoothing.enabled=false", "simulation.enabled=false"])
    outputs.write_discrete_outputs(plan(cfg, progress=False), tmp_path)
    assert titles == ["Swarm energy, MRF method bp"]
    assert (tmp_path / "figures" / "swarm_energy.png").is_file()


def test_a_distance_figures_title_sits_above_its_legend(tmp_path, monkeypatch):
    saved = []
    monkeypatch.setattr(plots, "save_figure", lambda fig, path, dpi=110: saved.append(fig) or path)
    t = np.linspace(0.0, 2.0, 21)
    plots.plot_distances(tmp_path / "d.png", t, np.full(21, 1.0), np.full(21, 2.0), 0.5, title="the stage")
    plots.plot_distances(tmp_path / "e.png", t, np.full(21, 1.0), np.full(21, 2.0), 0.5)
    titled, plain = saved
    titled.canvas.draw()
    legend = titled.axes[0].get_legend().get_window_extent()
    assert titled._suptitle.get_text() == "the stage" and titled._suptitle.get_window_extent().y0 >= legend.y1
    assert plain._suptitle is None
    for fig in saved:
        plots._plt().close(fig)


@pytest.mark.parametrize("steps", [3, 0])
def test_figures_per_mrf_step_tick_whole_steps(tmp_path, monkeypatch, steps):
    """A short plan's step axes had ticks at 0.5, 1.5, 2.5 (a tour's 3-step plan); one of 0 steps at -0.04 to 0.04,
    its distances not drawn at all (one point, no line)."""
    saved = []
    monkeypatch.setattr(plots, "save_figure", lambda fig, path, dpi=110: saved.append(fig) or path)
    e = np.linspace(10.0, 5.0, steps + 1)
    plots.plot_energy(tmp_path / "e.png", {"icm": e})
    plots.plot_distances(tmp_path / "d.png", np.arange(steps + 1), e / 10, e / 5, 0.5, xlabel="MRF step")
    for fig in saved:
        fig.canvas.draw()
        ax = fig.axes[0]
        lo, hi = ax.get_xlim()
        ticks = [v for v in ax.get_xticks() if lo <= v <= hi]
        assert ticks and all(float(v).is_integer() for v in ticks), ticks
        assert all(line.get_marker() not in (None, "None", "") for line in ax.get_lines()[:2]) if steps == 0 else True
        plots._plt().close(fig)


@pytest.mark.parametrize("size", [(50, 6, 4), (32, 16, 8)], ids=["flat", "field"])
def test_3d_figures_and_animation_frames_keep_their_labels_inside(tmp_path, size):
    """A flat voxel map's GIF (50 x 6 x 4 m, heights drawn x2.5) cut its z-y view's label to "z [m], drawn x2." at
    the frame's right edge and the x-z view's "x [m]" at its bottom (its paths figure too), and field3d's size of map
    touched the frame's left edge with "z [m]": nothing drawn may touch a picture's edges."""
    from PIL import Image

    grid = OccupancyGrid(np.zeros(size), 1.0, (0.0, 0.0, 0.5))
    t = np.array([0.0, 0.2])
    pos = np.array([[[1.0, 2.0, 1.5], [3.0, 4.0, 2.5]], [[1.5, 2.0, 1.5], [3.5, 4.0, 2.5]]])
    goal = np.array([size[0] - 3.0, 3.0, 1.5])
    plots.animate(tmp_path / "a.gif", grid, t, pos, goal)
    plots.plot_paths(tmp_path / "p.png", grid, [pos[:, i] for i in range(2)], goal, "smoothed")
    for picture in ("a.gif", "p.png"):
        ink = np.asarray(Image.open(tmp_path / picture).convert("L")).astype(int) < 128
        edges = {"left": ink[:, :2], "right": ink[:, -2:], "top": ink[:2], "bottom": ink[-2:]}
        assert not any(e.any() for e in edges.values()), (picture, {k: int(e.sum()) for k, e in edges.items()})


@pytest.mark.parametrize(("size", "res"), [((40, 40), 1.0), ((24, 16), 0.25), ((60, 8), 1.0), ((20, 40), 1.0)],
                         ids=["square", "arena", "wide", "tall"])
def test_a_2d_animation_has_no_blank_band_above_its_title(tmp_path, size, res):
    """The 2-D GIFs (paper_figs' anim_*.gif, a run's --animate) had 57 blank rows above the title and 35 below the x
    label: their figure's height had room for a legend the animation does not draw. Every frame now ends within
    tight_layout's pad (12 px) of what it draws, above and below, and keeps its 400 px width; nothing is cut (a
    layout of the wide map cut its y labels at the left edge). The tall map is drawn narrower than the GIF, as
    before (view_figure's height is at most 1.5 times the width)."""
    from PIL import Image

    grid = OccupancyGrid(np.zeros(size), res)
    t = np.array([0.0, 9.5, 123.4])
    pos = res * np.array([[[1.0, 2.0], [3.0, 4.0]], [[5.0, 6.0], [7.0, 3.0]], [[9.0, 2.0], [9.0, 4.0]]])
    plots.animate(tmp_path / "a.gif", grid, t, pos, res * np.array([10.0, 3.0]))
    gif = Image.open(tmp_path / "a.gif")
    assert gif.size[0] == 400
    for k in range(gif.n_frames):
        gif.seek(k)
        ink = np.asarray(gif.convert("L")) < 250
        rows, cols = np.flatnonzero(ink.any(axis=1)), np.flatnonzero(ink.any(axis=0))
        blank = {"above": rows[0], "below": gif.size[1] - 1 - rows[-1], "left": cols[0],
                 "right": gif.size[0] - 1 - cols[-1]}
        assert all(v > 0 for v in blank.values()), (k, blank)
        kept = ("above", "below") if size == (20, 40) else tuple(blank)
        assert all(blank[side] <= 16 for side in kept), (k, blank)


def test_a_big_maps_thin_walls_are_all_drawn():
    """A 2000 x 2000 MovingAI map with two walls one cell thick across it (a map tour): its figures drew the wall at
    y = 1500 and not the one at y = 500, the nearest-neighbour resampling to a few hundred pixels keeping one cell
    row in seven. Each wall is drawn where it is (the map in blocks of cells, shaded by their occupied fraction as a
    voxel column is)."""
    plt = plots._plt()
    occ = np.zeros((2000, 2000), dtype=bool)
    walls = [300, 500, 700, 1100, 1500, 1901]
    occ[100:1900, walls] = True
    grid = OccupancyGrid.from_occupied(occ)
    fig, ax = plt.subplots(figsize=(6, 6), dpi=110)
    plots.draw_map(ax, grid)
    fig.canvas.draw()
    rgba = np.asarray(fig.canvas.buffer_rgba())
    height = rgba.shape[0]
    x_mid = ax.transData.transform((1000.0, 0.0))[0]
    for y in walls:
        y_px = ax.transData.transform((1000.0, y))[1]
        row = int(round(height - y_px))
        band = rgba[row - 1:row + 2, int(x_mid) - 50:int(x_mid) + 50, 0]  # red channel: 255 white
        assert (band.min(axis=0) <= 255 * plots.OCCUPIED_GREY).all(), f"wall at y = {y} not drawn"
    assert (rgba[int(round(height - ax.transData.transform((1000.0, 1000.0))[1])), int(x_mid), :3] == 255).all()
    assert tuple(ax.get_xlim()) == (grid.extent[0], grid.extent[1])
    assert tuple(ax.get_ylim()) == (grid.extent[2], grid.extent[3])
    plt.close(fig)


def test_a_log_axis_of_two_decades_has_no_crowded_labels():
    """Fig. 8b's time per MRF step (1.3 to 125 ms) labelled every minor tick: 50, 60, 70, 80, 90, 100 stacked."""
    plt = plots._plt()
    with plots.paper_style():
        fig, ax = plt.subplots(figsize=(5.5, 4.6), dpi=100)
        ax.plot([5, 2000], [1.3, 125.0])
        ax.set_xscale("log")
        ax.set_yscale("log")
        plots.plain_log_ticks(ax.yaxis)
        fig.canvas.draw()
        renderer = fig.canvas.get_renderer()
        lo, hi = ax.get_ylim()
        labels = [t for t in ax.yaxis.get_ticklabels(minor=False) + ax.yaxis.get_ticklabels(minor=True)
                  if t.get_visible() and t.get_text() and lo <= t.get_position()[1] <= hi]
        texts = sorted((t.get_text() for t in labels), key=float)
        assert texts == ["2", "3", "5", "10", "20", "30", "50", "100"]  # plain numbers, not 10^1
        boxes = sorted((t.get_window_extent(renderer) for t in labels), key=lambda b: b.y0)
        assert all(b.y0 >= a.y1 for a, b in zip(boxes, boxes[1:])), "tick labels overlap"
    plt.close(fig)
