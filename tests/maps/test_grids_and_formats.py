"""Occupancy grids, map formats, world <-> cell conversion (mrfswarm.maps)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mrfswarm.config import load_config
from mrfswarm.errors import ConfigError, ScenarioError
from mrfswarm.maps import OccupancyGrid, load_map, read_movingai, read_ros, save_movingai, save_ros
from support.repository import TEST_DATA

MAP_FILES = TEST_DATA / "maps"


def cells(mask: np.ndarray) -> set[tuple[int, int]]:
    return {(int(i), int(j)) for i, j in np.argwhere(mask)}


def write(path: Path, content: str | bytes) -> Path:
    if isinstance(content, str):
        path.write_text(content)
    else:
        path.write_bytes(content)
    return path


ROS_META = "image: {image}\nresolution: 1.0\norigin: [0.0, 0.0, 0.0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n"


def ros_map(tmp_path: Path, image_bytes: bytes | None, meta: str | None = None, name: str = "m.pgm") -> Path:
    if image_bytes is not None:
        write(tmp_path / name, image_bytes)
    return write(tmp_path / "m.yaml", (meta or ROS_META).format(image=name))


# -- the grid ------------------------------------------------------------------------


def test_grid_properties_and_extent():
    prob = np.zeros((4, 3))
    prob[1, 2] = 0.5  # exactly the threshold: occupied
    prob[3, 0] = 0.49
    g = OccupancyGrid(prob, resolution=0.5, origin=(10.0, -2.0))
    assert g.shape == (4, 3) and g.width == 4 and g.height == 3
    assert cells(g.occupied) == {(1, 2)}
    assert np.array_equal(g.free, ~g.occupied)
    assert g.extent == (9.75, 11.75, -2.25, -0.75)
    with pytest.raises(ValueError):
        g.prob[0, 0] = 1.0  # read-only: the dataclass is frozen, so is its array
    prob[0, 0] = 1.0
    assert g.prob[0, 0] == 0.0  # the grid owns a copy


def test_grid_pickles_and_stays_read_only():
    import pickle

    g = OccupancyGrid(np.array([[0.0, 0.7]]), resolution=0.5, origin=(1.0, 2.0))
    _ = g.occupied  # a cached array must not travel as stale state
    h = pickle.loads(pickle.dumps(g))
    assert h == g and not h.prob.flags.writeable and cells(h.occupied) == {(0, 1)}


def test_from_occupied_and_equality():
    occ = np.zeros((3, 2), dtype=bool)
    occ[2, 1] = True
    g = OccupancyGrid.from_occupied(occ, resolution=2.0, origin=(1, 1))
    assert g.prob.dtype == np.float64 and g.prob[2, 1] == 1.0 and g.prob.sum() == 1.0
    assert g == OccupancyGrid.from_occupied(occ.copy(), 2.0, (1.0, 1.0))
    assert g != OccupancyGrid.from_occupied(occ, 1.0, (1.0, 1.0))
    assert g != OccupancyGrid.from_occupied(~occ, 2.0, (1.0, 1.0))
    with pytest.raises(ScenarioError, match="boolean"):
        OccupancyGrid.from_occupied(occ.astype(int))


@pytest.mark.parametrize("prob, resolution, origin, match", [
    (np.full((2, 2), 1.5), 1.0, (0, 0), r"prob\[0, 0\] = 1\.5"),
    (np.full((2, 2), np.nan), 1.0, (0, 0), "nan"),
    (np.zeros(3), 1.0, (0, 0), r"shape \(W, H\)"),
    (np.zeros((2, 2, 2, 2)), 1.0, (0, 0), r"\(W, H, D\)"),
    (np.zeros((0, 3)), 1.0, (0, 0), r"\(0, 3\)"),
    (np.zeros((2, 2)), 0.0, (0, 0), "resolution = 0.0"),
    (np.zeros((2, 2)), -1, (0, 0), "resolution = -1"),
    (np.zeros((2, 2)), 1.0, (0, 0, 0), r"origin = \(0, 0, 0\)"),
    (np.zeros((2, 2)), 1.0, (0, np.inf), "origin"),
])
def test_grid_rejects_bad_data(prob, resolution, origin, match):
    with pytest.raises(ScenarioError, match=match):
        OccupancyGrid(prob, resolution=resolution, origin=origin)


def test_world_to_cell_default_frame():
    """1 m cells at origin 0: cell (i, j) is centred at (i, j), covers [i-0.5, i+0.5)."""
    g = OccupancyGrid(np.zeros((40, 40)))
    pts = np.array([[4.0, 16.0], [4.49, 16.2], [4.5, 16.0], [3.5, 15.5], [-0.5, -0.5], [-0.51, 0.0], [39.49, 39.5]])
    assert world_to_cell_list(g, pts) == [(4, 16), (4, 16), (5, 16), (4, 16), (0, 0), (-1, 0), (39, 40)]
    assert g.in_bounds(g.world_to_cell(pts)).tolist() == [True] * 5 + [False, False]
    assert np.array_equal(g.snap(np.array([[4.4, 15.6], [-3.2, 0.1]])), [[4.0, 16.0], [-3.0, 0.0]])


def test_voxel_grid_is_the_same_grid_one_axis_more():
    """A (W, H, D) grid: voxel (i, j, k) centred at origin + res (i, j, k); points and cells are (..., 3)."""
    occ = np.zeros((4, 3, 2), dtype=bool)
    occ[1, 2, 1] = True
    g = OccupancyGrid.from_occupied(occ, resolution=0.5, origin=(1.0, 2.0, 3.0))
    assert g.ndim == 3 and g.shape == (4, 3, 2) and g.depth == 2
    assert g.cell_to_world(np.array([1, 2, 1])).tolist() == [1.5, 3.0, 3.5]
    assert g.world_to_cell(np.array([[1.5, 3.0, 3.5], [1.5, 3.0, 3.74], [1.5, 3.0, 3.75]])).tolist() == [
        [1, 2, 1], [1, 2, 1], [1, 2, 2]]
    ij = np.array([[1, 2, 1], [1, 2, 0], [0, 0, 2], [0, 0, -1], [3, 2, 1]])
    assert g.is_free(ij).tolist() == [False, True, False, False, True]
    assert g.in_bounds(ij).tolist() == [True, True, False, False, True]
    lo, hi = g.bounds
    assert lo.tolist() == [0.75, 1.75, 2.75] and hi.tolist() == [2.75, 3.25, 3.75]
    assert OccupancyGrid(np.zeros((2, 2, 2))).origin == (0.0, 0.0, 0.0)  # a 2-D origin puts z at 0
    assert OccupancyGrid(np.zeros((2, 2, 2)), origin=(1.0, 2.0)).origin == (1.0, 2.0, 0.0)
    with pytest.raises(ScenarioError, match=r"\(\.\.\., 3\)"):
        g.world_to_cell(np.zeros((4, 2)))
    with pytest.raises(ScenarioError, match=r"prob\[1, 0, 1\] = 2\.0"):
        OccupancyGrid(np.where(np.arange(8).reshape(2, 2, 2) == 5, 2.0, 0.0))
    assert "4 x 3 x 2 cells" in repr(g) and OccupancyGrid(np.zeros((4, 3))).bounds[1].tolist() == [3.5, 2.5]


def world_to_cell_list(g, pts):
    return [tuple(int(v) for v in ij) for ij in g.world_to_cell(pts)]


def test_conversions_are_vectorized():
    g = OccupancyGrid(np.zeros((5, 5)), resolution=0.25, origin=(1.0, 2.0))
    p = np.random.default_rng(0).uniform(0, 3, size=(3, 4, 2))
    ij = g.world_to_cell(p)
    assert ij.shape == (3, 4, 2) and ij.dtype == np.int64
    assert g.cell_to_world(ij).shape == (3, 4, 2)
    assert g.in_bounds(ij).shape == (3, 4) and g.is_free(ij).shape == (3, 4)
    assert g.world_to_cell([1.0, 2.0]).tolist() == [0, 0]  # a single point, (2,)
    with pytest.raises(ScenarioError, match=r"\(\.\.\., 2\)"):
        g.world_to_cell(np.zeros((4, 3)))
    with pytest.raises(ScenarioError, match="finite"):
        g.world_to_cell([np.nan, 0.0])


def test_is_free_off_map_and_occupied():
    occ = np.zeros((3, 3), dtype=bool)
    occ[1, 1] = True
    g = OccupancyGrid.from_occupied(occ)
    ij = np.array([[0, 0], [1, 1], [-1, 0], [3, 0], [0, 3], [2, 2], [0, -5]])
    assert g.is_free(ij).tolist() == [True, False, False, False, False, True, False]
    assert g.in_bounds(ij).tolist() == [True, True, False, False, False, True, False]


settings.register_profile("maps", deadline=None, max_examples=150, suppress_health_check=[HealthCheck.too_slow])

resolutions = st.floats(0.01, 10.0)
origins = st.tuples(st.floats(-1000, 1000), st.floats(-1000, 1000))
cell_idx = st.tuples(st.integers(-2000, 2000), st.integers(-2000, 2000))


@settings(settings.get_profile("maps"))
@given(res=resolutions, origin=origins, ij=cell_idx, frac=st.tuples(st.floats(-0.4999, 0.4999), st.floats(-0.4999, 0.4999)))
def test_round_trips_and_boundaries(res, origin, ij, frac):
    g = OccupancyGrid(np.zeros((2, 2)), resolution=res, origin=origin)
    ij = np.array(ij)
    c = g.cell_to_world(ij)
    assert np.allclose(c, np.array(origin) + res * ij, rtol=0, atol=1e-9 * (1 + np.abs(c)).max())
    assert np.array_equal(g.world_to_cell(c), ij)
    # any point strictly inside the cell maps back to it, and snaps to its centre
    p = c + res * np.array(frac)
    assert np.array_equal(g.world_to_cell(p), ij)
    assert np.allclose(g.snap(p), c)
    # the lower edge belongs to the cell, the upper edge to the next cell
    assert np.array_equal(g.world_to_cell(c - res / 2), ij)
    assert np.array_equal(g.world_to_cell(c + res / 2), ij + 1)


@settings(settings.get_profile("maps"))
@given(res=resolutions, origin=origins, w=st.integers(1, 30), h=st.integers(1, 30),
       u=st.tuples(st.floats(-0.5, 1.5), st.floats(-0.5, 1.5)))
def test_in_bounds_matches_extent(res, origin, w, h, u):
    g = OccupancyGrid(np.zeros((w, h)), resolution=res, origin=origin)
    x0, x1, y0, y1 = g.extent
    p = np.array([x0 + u[0] * (x1 - x0), y0 + u[1] * (y1 - y0)])
    margin = 1e-6 * res
    inside = x0 + margin < p[0] < x1 - margin and y0 + margin < p[1] < y1 - margin
    outside = p[0] < x0 - margin or p[0] > x1 + margin or p[1] < y0 - margin or p[1] > y1 + margin
    got = bool(g.in_bounds(g.world_to_cell(p)))
    if inside:
        assert got
    if outside:
        assert not got


# -- free and boxes --------------------------------------------------------------------


def test_free_map():
    g = load_map({"kind": "free", "size": [7, 3]}, ".")
    assert g.shape == (7, 3) and not g.occupied.any()
    assert g.resolution == 1.0 and g.origin == (0.0, 0.0)
    g = load_map({"kind": "free", "size": [2, 2], "resolution": 0.5, "origin": [1, -1]}, ".")
    assert g.resolution == 0.5 and g.origin == (1.0, -1.0)
    assert np.array_equal(g.cell_to_world([1, 1]), [1.5, -0.5])


def corridor_spec(size=40):
    return {"kind": "boxes", "size": [size, size], "boxes": [
        {"center": [19.5, 32.5], "size": [18, 16]}, {"center": [19.5, 9.5], "size": [18, 16]}]}


def test_narrow_corridor_geometry():
    """Two 18 x 16 m blocks: x 10.5..28.5 -> cells 11..28; y 1.5..17.5 -> 2..17 and 24.5..40.5 -> 25..39."""
    g = load_map(corridor_spec(), ".")
    assert g.shape == (40, 40)
    expected = np.zeros((40, 40), dtype=bool)
    expected[11:29, 2:18] = True
    expected[11:29, 25:40] = True
    assert np.array_equal(g.occupied, expected)
    assert g.occupied.sum() == 18 * 16 + 18 * 15  # the upper block is cut by the map's top edge
    # the passage: along the whole blocks' length, free cells exactly y = 18..24 (7 cells)
    for x in range(11, 29):
        free_y = np.flatnonzero(g.free[x, 2:40]) + 2
        assert free_y.tolist() == list(range(18, 25))
    # the drones' start cells (x in {4, 5}, y in 16..24) and the goal (35, 20) are free
    starts = np.array([[x, y] for x in (4, 5) for y in (16, 18, 20, 22, 24)])
    assert g.is_free(g.world_to_cell(starts)).all()
    assert g.is_free(g.world_to_cell(np.array([35.0, 20.0])))


def test_blocks_geometry():
    """Edges on integers (12.5 +- 2.5 = 10, 15) pass through cell centres: the half-open box takes 10..14."""
    spec = {"kind": "boxes", "size": [40, 40], "boxes": [
        {"center": [12.5, 12.5], "size": [5, 5]}, {"center": [12.5, 27.5], "size": [5, 5]},
        {"center": [35, 27.5], "size": [10, 5]}]}
    g = load_map(spec, ".")
    expected = np.zeros((40, 40), dtype=bool)
    expected[10:15, 10:15] = True  # 5 x 5 m -> 5 x 5 cells
    expected[10:15, 25:30] = True
    expected[30:40, 25:30] = True  # 10 x 5 m
    assert np.array_equal(g.occupied, expected)
    starts = np.array([[x, y] for x in (2, 4, 6) for y in (5, 7, 9, 11)])
    assert g.is_free(starts).all() and g.is_free(np.array([35, 15]))


@pytest.mark.parametrize("res", [0.1, 0.3, 0.05, 0.7, 1.0])
def test_box_edges_on_cell_centres_are_inside(res):
    """Edges exactly on cell centres (a * res, b * res) take cells a..b-1 on both axes, whatever the rounding."""
    for a, b in [(1, 3), (5, 7), (3, 11), (7, 8), (10, 19)]:
        for ay, by in [(a, b), (b, 2 * b - a)]:
            box = {"center": [(a + b) / 2 * res, (ay + by) / 2 * res], "size": [(b - a) * res, (by - ay) * res]}
            g = load_map({"kind": "boxes", "size": [40, 40], "resolution": res, "boxes": [box]}, ".")
            expected = np.zeros((40, 40), dtype=bool)
            expected[a:b, ay:by] = True
            assert np.array_equal(g.occupied, expected), (a, b, ay, by)


def test_box_outside_map_warns(caplog):
    g = load_map({"kind": "boxes", "size": [5, 5], "boxes": [{"center": [50, 50], "size": [2, 2]}]}, ".")
    assert not g.occupied.any()
    assert "boxes[0] (center [50, 50], size [2, 2]) overlaps no cell of the 5 x 5 map" in caplog.text


def box_warnings(caplog) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.name == "mrfswarm.maps.inline"]


def test_a_box_reaching_past_its_cells_is_a_warning_naming_it(caplog):
    """Under the default fill (cell centres) a box off the cell faces reaches past its cells: one line per box."""
    spec = {"kind": "boxes", "size": [8, 8], "boxes": [
        {"center": [2, 2], "size": [1.8, 1.8]},  # [1.1, 2.9): cell 2 alone, 0.4 m past it on every side
        {"center": [5.5, 5.5], "size": [2, 2]},  # [4.5, 6.5): cells 5, 6 exactly, no warning
        {"center": [5, 1.5], "size": [2, 2]},  # x [4, 6) on cell centres: cells 4, 5, reaching 0.5 m past x = 5.5
        {"center": [7.5, 7.5], "size": [2, 2]}]}  # cells 7, past the map's edge: dropped, not a warning
    g = load_map(spec, ".")
    assert cells(g.occupied) == {(2, 2), (5, 5), (5, 6), (6, 5), (6, 6), (4, 1), (4, 2), (5, 1), (5, 2), (7, 7)}
    lines = box_warnings(caplog)
    assert len(lines) == 2, lines
    assert lines[0].startswith("scenario.map.boxes[0] (center [2, 2], size [1.8, 1.8]) reaches 0.4 m past the cells "
                               "it fills")
    assert lines[1].startswith("scenario.map.boxes[2] (center [5, 1.5], size [2, 2]) reaches 0.5 m past")
    assert all('align its faces with the cells\'' in t and 'scenario.map.fill = "overlap"' in t for t in lines)
    caplog.clear()
    load_map({**spec, "fill": "overlap"}, ".")
    assert not box_warnings(caplog)
    load_map({**spec, "fill": "centres"}, ".")  # the rule chosen in the map: the same cells, no warning
    assert not box_warnings(caplog)


def test_a_box_holding_no_cell_centre_is_a_warning(caplog):
    """A 0.8 m box between four cell centres fills no cell: the obstacle is gone from the map."""
    g = load_map({"kind": "boxes", "size": [5, 5], "boxes": [{"center": [2.5, 2.5], "size": [0.8, 0.8]}]}, ".")
    assert not g.occupied.any()
    (line,) = box_warnings(caplog)
    assert line.startswith("scenario.map.boxes[0] (center [2.5, 2.5], size [0.8, 0.8]) holds no cell centre of the "
                           "5 x 5 map, so it fills no cell")
    g = load_map({"kind": "boxes", "size": [5, 5], "fill": "overlap",
                  "boxes": [{"center": [2.5, 2.5], "size": [0.8, 0.8]}]}, ".")
    assert cells(g.occupied) == {(2, 2), (2, 3), (3, 2), (3, 3)}


def test_fill_overlap_takes_every_cell_a_box_overlaps():
    """[1.1, 2.9) x [0.2, 3.6) meets cells 1..3 along x (faces 0.5, 1.5, 2.5, 3.5) and 0..4 along y."""
    g = load_map({"kind": "boxes", "size": [6, 6], "fill": "overlap",
                  "boxes": [{"center": [2, 1.9], "size": [1.8, 3.4]}]}, ".")
    assert cells(g.occupied) == {(i, j) for i in (1, 2, 3) for j in range(5)}
    centres = load_map({"kind": "boxes", "size": [6, 6], "boxes": [{"center": [2, 1.9], "size": [1.8, 3.4]}]}, ".")
    assert cells(centres.occupied) == {(2, j) for j in (1, 2, 3)}


@pytest.mark.parametrize("res", [0.1, 0.3, 0.05, 0.7, 1.0])
def test_fill_overlap_of_boxes_on_cell_faces_is_the_centres_fill(res):
    """Faces on cell faces ((a - 1/2) res, (b - 1/2) res): cells a..b-1 under both fills, L / res of them, whatever
    the rounding; the cells a - 1 and b, which the box touches along a face only, stay free."""
    for a, b in [(1, 3), (5, 7), (3, 11), (7, 8), (10, 19)]:
        for ay, by in [(a, b), (b, 2 * b - a)]:
            box = {"center": [(a + b - 1) / 2 * res, (ay + by - 1) / 2 * res],
                   "size": [(b - a) * res, (by - ay) * res]}
            expected = np.zeros((40, 40), dtype=bool)
            expected[a:b, ay:by] = True
            for fill in ("centres", "overlap"):
                g = load_map({"kind": "boxes", "size": [40, 40], "resolution": res, "fill": fill, "boxes": [box]}, ".")
                assert np.array_equal(g.occupied, expected), (fill, a, b, ay, by)


@settings(max_examples=80, deadline=None)
@given(shape=st.tuples(st.integers(1, 12), st.integers(1, 12)),
       res=st.sampled_from([1.0, 0.5, 0.3, 0.25, 0.1]),
       origin=st.tuples(*[st.sampled_from([0.0, 0.125, -1.0, 2.5, 0.05])] * 2),
       raw=st.lists(st.tuples(st.tuples(*[st.floats(-1, 5)] * 2), st.tuples(*[st.floats(0.01, 3)] * 2)),
                    min_size=1, max_size=5),
       seed=st.integers(0, 2**32 - 1))
def test_fill_overlap_leaves_no_point_of_a_box_in_a_free_cell(shape, res, origin, raw, seed):
    """Independent of the loader: random points of every box land in occupied cells (or off the map), and every
    occupied cell's open square meets some box's open one (interval arithmetic: a face-on-face touch is no overlap)."""
    boxes = [{"center": list(c), "size": list(s)} for c, s in raw]
    g = load_map({"kind": "boxes", "size": list(shape), "resolution": res, "origin": list(origin), "fill": "overlap",
                  "boxes": boxes}, ".")
    rng = np.random.default_rng(seed)
    lo = np.array([b["center"] for b in boxes]) - np.array([b["size"] for b in boxes]) / 2
    hi = lo + np.array([b["size"] for b in boxes])
    pts = rng.uniform(lo[:, None, :], hi[:, None, :], size=(len(boxes), 200, 2)).reshape(-1, 2)
    pts = np.concatenate([pts, lo + 1e-6 * res, hi - 1e-6 * res, (lo + hi) / 2])  # corners just inside, centres
    ij = np.floor((pts - np.array(origin)) / res + 0.5).astype(int)
    on = (ij >= 0).all(axis=1) & (ij < np.array(shape)).all(axis=1)
    assert g.occupied[ij[on, 0], ij[on, 1]].all()
    for i, j in np.argwhere(g.occupied):
        c_lo = np.array(origin) + res * np.array([i, j]) - res / 2
        assert ((c_lo + res > lo) & (c_lo < hi)).all(axis=1).any(), (i, j)


# -- ascii ------------------------------------------------------------------------------


def test_ascii_orientation():
    rows = ["....", "...#", "@OT."]
    g = load_map({"kind": "ascii", "rows": rows}, ".")
    assert g.shape == (4, 3)
    assert cells(g.occupied) == {(3, 1), (0, 2), (1, 2), (2, 2)}  # row 1 column 3 -> [3, 1]; no flip


def test_ascii_with_placement():
    g = load_map({"kind": "ascii", "rows": ["#.", ".."], "resolution": 2.0, "origin": [-1, 5]}, ".")
    assert cells(g.occupied) == {(0, 0)}
    assert not g.is_free(g.world_to_cell(np.array([-1.9, 5.9])))
    assert g.is_free(g.world_to_cell(np.array([0.1, 5.0])))


# -- MovingAI ---------------------------------------------------------------------------


def test_movingai_fixture():
    """small.map: '@' at row 0 col 1, 'T' at row 1 col 2, 'O' at row 2 col 4; G, S, W free."""
    g = load_map({"kind": "movingai", "path": "small.map"}, MAP_FILES)
    assert g.shape == (5, 4) and g.resolution == 1.0 and g.origin == (0.0, 0.0)
    assert cells(g.occupied) == {(1, 0), (2, 1), (4, 2)}
    assert g.is_free(np.array([[4, 1], [0, 2], [1, 2]])).all()  # G, S, W (water is free for flyers)


def test_movingai_with_resolution_and_origin():
    """The file has no scale: the config's resolution and origin place its cells (centre of cell (0, 0) at origin)."""
    g = load_map({"kind": "movingai", "path": "small.map", "resolution": 0.25, "origin": [1, -2]}, MAP_FILES)
    assert g.shape == (5, 4) and g.resolution == 0.25 and g.origin == (1.0, -2.0)
    assert cells(g.occupied) == {(1, 0), (2, 1), (4, 2)}  # the same cells as at 1 m
    assert g.cell_to_world(np.array([2, 1])).tolist() == [1.5, -1.75]  # the 'T': centre origin + 0.25 * (2, 1)
    assert g.world_to_cell(np.array([1.5 + 0.124, -1.75 - 0.125])).tolist() == [2, 1]
    assert not g.is_free(g.world_to_cell(np.array([1.5, -1.75])))
    assert g.extent == (0.875, 2.125, -2.125, -1.125)


def test_movingai_tolerates_crlf_swapped_dims_and_trailing_blank_lines(tmp_path):
    p = write(tmp_path / "a.map", "type octile\r\nwidth 3\r\nheight 2\r\nmap\r\n@..\r\n..T\r\n\r\n\r\n")
    g = read_movingai(p)
    assert g.shape == (3, 2) and cells(g.occupied) == {(0, 0), (2, 1)}


def test_movingai_skips_a_byte_order_mark(tmp_path):
    """A map saved by an editor that writes a UTF-8 byte-order mark was refused as "not an ASCII MovingAI map (byte
    0xef at offset 0)" (a map tour); the TOML config and the ROS YAML beside it were read. The mark is skipped."""
    p = tmp_path / "bom.map"
    p.write_bytes(b"\xef\xbb\xbftype octile\nheight 2\nwidth 3\nmap\n@..\n..T\n")
    g = read_movingai(p)
    assert g.shape == (3, 2) and cells(g.occupied) == {(0, 0), (2, 1)}


def test_movingai_round_trip(tmp_path):
    rng = np.random.default_rng(1)
    occ = rng.random((13, 7)) < 0.3
    g = OccupancyGrid.from_occupied(occ)
    save_movingai(g, tmp_path / "r.map")
    assert read_movingai(tmp_path / "r.map") == g
    text = (tmp_path / "r.map").read_text().splitlines()
    assert text[:4] == ["type octile", "height 7", "width 13", "map"]
    assert text[4 + 2][5] == ("@" if occ[5, 2] else ".")  # row y = line y


def test_movingai_save_drops_placement_with_warning(tmp_path, caplog):
    g = OccupancyGrid(np.array([[0.7, 0.2]]), resolution=0.5, origin=(1.0, 0.0))
    save_movingai(g, tmp_path / "x.map")
    back = read_movingai(tmp_path / "x.map")
    assert back == OccupancyGrid.from_occupied(g.occupied)
    assert "resolution 0.5" in caplog.text


# -- ROS --------------------------------------------------------------------------------


def test_ros_p2_fixture():
    """Top image row dark -> occupied[:, H-1]; unknown (205) -> 0.5 -> occupied; bottom-right dark -> (3, 0)."""
    g = load_map({"kind": "ros", "path": "small_p2.yaml"}, MAP_FILES)
    assert g.shape == (4, 3) and g.resolution == 0.5
    assert g.origin == (-0.75, 2.25)  # ROS origin is the corner of cell (0, 0): centre = corner + res/2
    assert np.array_equal(g.occupied[:, 2], [True] * 4)
    assert cells(g.occupied) == {(0, 2), (1, 2), (2, 2), (3, 2), (1, 1), (3, 0)}
    assert g.prob[1, 1] == 0.5 and g.prob[3, 0] == 1.0 and g.prob[0, 0] == 0.0
    # world: the ROS corner (-1, 2) is the lower-left edge of cell (0, 0)
    assert g.world_to_cell(np.array([-1.0, 2.0])).tolist() == [0, 0]
    assert g.world_to_cell(np.array([-1.001, 2.0])).tolist() == [-1, 0]
    assert g.extent == (-1.0, 1.0, 2.0, 3.5)


def test_ros_config_may_state_the_yaml_frame_but_not_change_it():
    """resolution/origin in the config must agree with the YAML (origin: the centre of cell (0, 0))."""
    ok = load_map({"kind": "ros", "path": "small_p2.yaml", "resolution": 0.5, "origin": [-0.75, 2.25]}, MAP_FILES)
    assert ok == load_map({"kind": "ros", "path": "small_p2.yaml"}, MAP_FILES)
    with pytest.raises(ConfigError, match=r"scenario\.map\.resolution = 0\.25 disagrees with the ROS map .*small_p2"
                                          r"\.yaml.*resolution 0\.5 m") as e:
        load_map({"kind": "ros", "path": "small_p2.yaml", "resolution": 0.25}, MAP_FILES)
    one_line(e)
    # the YAML's origin is a corner; giving it as our origin (a centre) is the mistake this catches
    with pytest.raises(ConfigError, match=r"scenario\.map\.origin = \[-1, 2\] disagrees .*centred at \[-0\.75, "
                                          r"2\.25\].*origin \[-1, 2\] is that cell's corner") as e:
        load_map({"kind": "ros", "path": "small_p2.yaml", "origin": [-1, 2]}, MAP_FILES)
    one_line(e)


def test_ros_p5_fixture_block_origin_list():
    g = read_ros(MAP_FILES / "small_p5.yaml")
    assert g.shape == (3, 2) and g.origin == (0.5, 0.5)
    assert cells(g.occupied) == {(1, 1), (0, 0)}


def pgm(w, h, values, maxval=255):
    return b"P5\n%d %d\n%d\n" % (w, h, maxval) + bytes(values)


@pytest.mark.parametrize("negate, expected", [(0, {(0, 0)}), (1, {(1, 0)})])
def test_ros_negate(tmp_path, negate, expected):
    meta = ROS_META.replace("negate: 0", f"negate: {negate}")
    g = read_ros(ros_map(tmp_path, pgm(2, 1, [0, 255]), meta))
    assert cells(g.occupied) == expected


def test_ros_scale_and_raw_modes(tmp_path):
    values = [0, 255, 128, 100]  # occ p = 1, 0, 0.498, 0.608
    meta = ROS_META + "mode: scale\n"
    g = read_ros(ros_map(tmp_path, pgm(4, 1, values), meta))
    p = (255 - np.array(values)) / 255
    ratio = np.rint(100 * (p - 0.196) / (0.65 - 0.196)) / 100
    assert np.allclose(g.prob[:, 0], [1.0, 0.0, ratio[2], ratio[3]])
    assert 0.6 < ratio[2] < 0.7 and 0.85 < ratio[3] < 0.95
    g = read_ros(ros_map(tmp_path, pgm(4, 1, [0, 40, 100, 101]), ROS_META + "mode: Raw\n"))
    assert np.allclose(g.prob[:, 0], [0.0, 0.4, 1.0, 0.5])


def test_ros_png_rgb_and_alpha(tmp_path):
    from PIL import Image

    rgba = np.zeros((2, 3, 4), dtype=np.uint8)
    rgba[..., 3] = 255
    rgba[0, 0, :3] = 255          # top-left white: free
    rgba[0, 1, :3] = (255, 255, 0)  # mean 170 -> p = 0.33: unknown in trinary
    rgba[1, 2, :3] = 255
    rgba[1, 2, 3] = 0             # transparent white: free in trinary, unknown in scale
    Image.fromarray(rgba, "RGBA").save(tmp_path / "m.png")
    g = read_ros(ros_map(tmp_path, None, name="m.png"))
    # image row 0 -> y = 1: white, unknown, black; row 1 -> y = 0: black, black, transparent white
    assert cells(g.occupied) == {(0, 0), (1, 0), (1, 1), (2, 1)}
    assert g.prob[1, 1] == 0.5 and g.prob[2, 0] == 0.0
    g = read_ros(ros_map(tmp_path, None, ROS_META + "mode: scale\n", name="m.png"))
    assert g.prob[2, 0] == 0.5  # not opaque -> unknown in scale mode


def test_ros_pgm_small_maxval_is_scaled(tmp_path):
    g = read_ros(ros_map(tmp_path, b"P2\n# maxval 15\n3 1\n15\n0 15 12\n"))
    assert g.prob[:, 0].tolist() == [1.0, 0.0, 0.5]  # 12/15 -> grey 204 -> p = 0.2: unknown


def test_ros_round_trip(tmp_path):
    rng = np.random.default_rng(2)
    prob = rng.choice([0.0, 0.5, 1.0], size=(9, 5))
    g = OccupancyGrid(prob, resolution=0.05, origin=(-3.2, 7.125))
    save_ros(g, tmp_path / "saved.yaml")
    assert (tmp_path / "saved.pgm").exists()
    back = read_ros(tmp_path / "saved.yaml")
    assert np.array_equal(back.prob, g.prob) and back.resolution == g.resolution
    assert back.origin == pytest.approx(g.origin, abs=1e-12)
    g2 = OccupancyGrid(prob, resolution=0.25, origin=(1.5, -2.0))  # dyadic values: exact
    save_ros(g2, tmp_path / "dy.yaml")
    assert read_ros(tmp_path / "dy.yaml") == g2


def test_ros_save_rounds_other_probabilities_by_threshold(tmp_path):
    g = OccupancyGrid(np.array([[0.2], [0.7], [0.5], [0.4999]]))
    save_ros(g, tmp_path / "t.yaml")
    back = read_ros(tmp_path / "t.yaml")
    assert back.prob[:, 0].tolist() == [0.0, 1.0, 0.5, 0.0]
    assert np.array_equal(back.occupied, g.occupied)


def test_ros_save_tiny_resolution_is_valid_yaml(tmp_path):
    g = OccupancyGrid(np.zeros((2, 2)), resolution=1e-5, origin=(0.0, 0.0))
    save_ros(g, tmp_path / "tiny.yaml")
    assert read_ros(tmp_path / "tiny.yaml").resolution == 1e-5


# -- config integration ----------------------------------------------------------------


def test_paths_relative_to_config_file(tmp_path):
    sub = tmp_path / "cfg"
    sub.mkdir()
    (sub / "maps").mkdir()
    save_movingai(OccupancyGrid.from_occupied(np.eye(3, dtype=bool)), sub / "maps" / "m.map")
    write(sub / "exp.toml", '[scenario]\ngoal = [1, 1]\nmap = {kind = "movingai", path = "maps/m.map"}\n')
    cfg = load_config(sub / "exp.toml")
    g = load_map(cfg.scenario.map, cfg.base_dir)
    assert cells(g.occupied) == {(0, 0), (1, 1), (2, 2)}


# -- bad input: the right error type, one line, naming the value ---------------------------


def one_line(excinfo) -> str:
    msg = str(excinfo.value)
    assert "\n" not in msg and msg
    return msg


@pytest.mark.parametrize("spec, match", [
    ("free", r"scenario\.map = 'free'"),
    ({"size": [3, 3]}, r"scenario\.map\.kind is missing"),
    ({"kind": "voxels"}, r"kind = 'voxels'.*free, boxes, ascii, movingai, ros"),
    ({"kind": "free", "size": [3, 3], "colour": "red"}, r"unknown key scenario\.map\.colour; allowed: kind, size"),
    ({"kind": "movingai", "path": "a.map", "scale": 2}, r"unknown key scenario\.map\.scale; allowed: kind, path, "
     r"resolution, origin"),
    ({"kind": "movingai", "path": "a.map", "resolution": 0}, r"scenario\.map\.resolution = 0: must be > 0"),
    ({"kind": "movingai", "path": "a.map", "origin": [1]}, r"scenario\.map\.origin = \[1\]"),
    ({"kind": "ros", "path": "a.yaml", "resolution": -0.05}, r"scenario\.map\.resolution = -0\.05: must be > 0"),
    ({"kind": "free"}, r"scenario\.map\.size is missing"),
    ({"kind": "free", "size": [0, 3]}, r"size\[0\] = 0: must be >= 1"),
    ({"kind": "free", "size": [3.0, 3]}, r"size\[0\] = 3\.0: must be an integer"),
    ({"kind": "free", "size": [True, 3]}, r"size\[0\] = True"),
    ({"kind": "free", "size": [3]}, r"size = \[3\]"),
    ({"kind": "free", "size": [100000, 100000]}, r"exceeds"),
    ({"kind": "free", "size": [3, 3], "resolution": 0}, r"resolution = 0: must be > 0"),
    ({"kind": "free", "size": [3, 3], "resolution": "1"}, r"resolution = '1'"),
    ({"kind": "free", "size": [3, 3], "origin": [0, "a"]}, r"origin\[1\] = 'a'"),
    ({"kind": "boxes", "size": [3, 3]}, r"boxes is missing"),
    ({"kind": "boxes", "size": [3, 3], "boxes": {"center": [1, 1]}}, r"boxes = .*must be a list"),
    ({"kind": "boxes", "size": [3, 3], "boxes": [{"center": [1, 1]}]}, r"boxes\[0\]\.size is missing"),
    ({"kind": "boxes", "size": [3, 3], "boxes": [{"center": [1, 1], "size": [1, 1], "h": 2}]},
     r"unknown key scenario\.map\.boxes\[0\]\.h"),
    ({"kind": "boxes", "size": [3, 3], "boxes": [{"center": [1, 1], "size": [1, -2]}]}, r"boxes\[0\]\.size\[1\] = -2"),
    ({"kind": "boxes", "size": [3, 3], "boxes": [], "fill": "center"},
     r"scenario\.map\.fill = 'center': must be one of centres, overlap$"),
    ({"kind": "ascii", "rows": []}, r"rows = \[\]"),
    ({"kind": "ascii", "rows": "..#"}, r"rows = '\.\.#'"),
    ({"kind": "ascii", "rows": ["...", "..", "..."]}, r"rows\[1\] has 2 characters, expected 3"),
    ({"kind": "ascii", "rows": ["...", ".x."]}, r"rows\[1\] column 1: unknown character 'x'"),
    ({"kind": "ascii", "rows": ["...", "..é"]}, r"rows\[1\] column 2: unknown character 'é'"),
    ({"kind": "ascii", "rows": [".", 3]}, r"rows\[1\] = 3"),
    ({"kind": "ascii", "rows": [""]}, r"rows\[0\] is empty"),
    ({"kind": "movingai"}, r"path is missing"),
    ({"kind": "ros", "path": 3}, r"path = 3"),
])
def test_bad_map_tables_are_config_errors(spec, match):
    with pytest.raises(ConfigError, match=match) as e:
        load_map(spec, ".")
    one_line(e)


HEADER = "type octile\nheight 2\nwidth 3\nmap\n"


@pytest.mark.parametrize("content, match", [
    (HEADER + "...\n...\n", None),  # control: valid
    (HEADER + "...\n..\n", r"line 6 has 2 characters, expected 3"),
    (HEADER + "...\n", r"height 2 but the file has 1 map lines"),
    (HEADER + "...\n...\n...\n", r"line 7: unexpected data"),
    (HEADER + "...\n.x.\n", r"line 6, column 1: unknown terrain character 'x'"),
    ("type octile\nheight 2\nwidth 3\n...\n...\n", r"line 4: expected 'map'"),
    ("height 2\nwidth 3\nmap\n...\n...\n", r"line 1: expected the MovingAI header"),
    ("type octile\nheight two\nwidth 3\nmap\n", r"line 2: height 'two' is not an integer"),
    ("type octile\nheight 0\nwidth 3\nmap\n", r"height 0 must be >= 1"),
    ("type octile\nheight 2\nheight 3\nmap\n", r"line 3: expected 'width <integer>'"),
    ("type octile\nheight 2\n", r"truncated header"),
    ("type octile\nheight 100000\nwidth 100000\nmap\n", r"exceeds"),
    ("", r"line 1"),
    (b"type octile\nheight 1\nwidth 1\nmap\n\xe9\n", r"not an ASCII .*byte 0xe9"),
])
def test_bad_movingai_files(tmp_path, content, match):
    p = write(tmp_path / "bad.map", content)
    if match is None:
        assert load_map({"kind": "movingai", "path": "bad.map"}, tmp_path).shape == (3, 2)
        return
    with pytest.raises(ScenarioError, match=match) as e:
        load_map({"kind": "movingai", "path": "bad.map"}, tmp_path)
    assert str(p) in one_line(e)


def test_missing_map_files(tmp_path):
    with pytest.raises(ScenarioError, match=r"cannot read MovingAI map .*nope\.map.*No such file") as e:
        load_map({"kind": "movingai", "path": "nope.map"}, tmp_path)
    one_line(e)
    with pytest.raises(ScenarioError, match=r"cannot read ROS map YAML .*nope\.yaml"):
        load_map({"kind": "ros", "path": "nope.yaml"}, tmp_path)
    with pytest.raises(ScenarioError, match=r"cannot read map image .*gone\.pgm"):
        read_ros(ros_map(tmp_path, None, name="gone.pgm"))
    with pytest.raises(ScenarioError, match=r"cannot read MovingAI map"):
        load_map({"kind": "movingai", "path": "."}, tmp_path)  # a directory


@pytest.mark.parametrize("meta, match", [
    (ROS_META.replace("origin: [0.0, 0.0, 0.0]", "origin: [0.0, 0.0, 0.3]"), r"origin yaw = 0\.3 rad is not supported"),
    (ROS_META.replace("origin: [0.0, 0.0, 0.0]", "origin: [0.0, 0.0]"), r"origin = \[0\.0, 0\.0\] must be a list \[x, y, yaw\]"),
    (ROS_META.replace("origin: [0.0, 0.0, 0.0]", "origin: [a, 0.0, 0.0]"), r"origin = 'a'"),
    (ROS_META.replace("resolution: 1.0", "resolution: -0.1"), r"resolution = -0\.1 must be > 0"),
    (ROS_META.replace("resolution: 1.0", "resolution: fine"), r"resolution = 'fine'"),
    (ROS_META.replace("resolution: 1.0\n", ""), r"missing key 'resolution'"),
    (ROS_META.replace("negate: 0", "negate: 2"), r"negate = 2 must be 0 or 1"),
    (ROS_META.replace("free_thresh: 0.196", "free_thresh: 0.8"), r"free_thresh = 0\.8 and occupied_thresh = 0\.65"),
    (ROS_META + "mode: fancy\n", r"mode = 'fancy'"),
    (ROS_META.replace("image: {image}", "image: ''"), r"image = '' must be a non-empty"),
    ("image: [unclosed\n", r"invalid YAML at line"),
    ("- just\n- a list\n", r"expected a YAML mapping"),
    ("image: m.pgm\nresolution: 2001-13-01\n", r"invalid YAML: ValueError: month must be in 1\.\.12"),
    ("image: 2001-01-01\nresolution: 1\norigin: [0, 0, 0]\nnegate: 0\noccupied_thresh: 0.6\nfree_thresh: 0.1\n",
     r"image = datetime\.date\(2001, 1, 1\) must be a non-empty file name"),
])
def test_bad_ros_yaml(tmp_path, meta, match):
    p = ros_map(tmp_path, pgm(1, 1, [0]), meta)
    with pytest.raises(ScenarioError, match=match) as e:
        read_ros(p)
    assert str(p) in one_line(e)


def test_ros_yaw_negative_zero_is_fine(tmp_path):
    meta = ROS_META.replace("origin: [0.0, 0.0, 0.0]", "origin: [0.0, 0.0, -0.000000]")
    assert read_ros(ros_map(tmp_path, pgm(1, 1, [0]), meta)).occupied[0, 0]


@pytest.mark.parametrize("image, match", [
    (pgm(2, 2, [0, 0, 0, 0], maxval=65535) + bytes(4), r"maxval 65535: 16-bit"),
    (pgm(3, 2, [0, 0, 0, 0]), r"truncated PGM: expected 6 bytes of pixel data \(3 x 2\), found 4"),
    (b"P5\n3\n", r"truncated PGM header \(no height\)"),
    (b"P5\n3 x\n255\n", r"PGM height 'x'"),
    (b"P2\n2 1\n255\n0\n", r"expected 2 samples \(2 x 1\), found 1"),
    (b"P2\n2 1\n255\n0 300\n", r"sample 300 exceeds maxval 255"),
    (b"P2\n2 1\n255\n0 1.5\n", r"sample '1\.5' is not an integer"),
    (b"P2\n0 1\n255\n", r"width and height must be >= 1"),
    (b"GIF89a garbage", r"not an image file"),
    (b"\x89PNG\r\n\x1a\n truncated", r"not an image file|unreadable image"),
])
def test_bad_ros_images(tmp_path, image, match):
    p = ros_map(tmp_path, image)
    with pytest.raises(ScenarioError, match=match) as e:
        read_ros(p)
    assert "m.pgm" in one_line(e)


def test_sixteen_bit_png_is_refused(tmp_path):
    from PIL import Image

    Image.fromarray(np.full((2, 2), 40000, dtype=np.uint16)).save(tmp_path / "m.png")
    with pytest.raises(ScenarioError, match=r"m\.png: image mode I.*16-bit"):
        read_ros(ros_map(tmp_path, None, name="m.png"))


def test_save_ros_refuses_image_name(tmp_path):
    with pytest.raises(ScenarioError, match="image's name"):
        save_ros(OccupancyGrid(np.zeros((1, 1))), tmp_path / "x.pgm")


def test_write_failures_are_scenario_errors(tmp_path):
    g = OccupancyGrid(np.zeros((1, 1)))
    with pytest.raises(ScenarioError, match="cannot write MovingAI map"):
        save_movingai(g, tmp_path / "no_dir" / "x.map")
    with pytest.raises(ScenarioError, match="cannot write map image"):
        save_ros(g, tmp_path / "no_dir" / "x.yaml")


@settings(settings.get_profile("maps"), max_examples=200)
@given(data=st.binary(max_size=80), prefix=st.sampled_from([b"", b"P5\n", b"P2\n", b"P5\n2 2\n255\n", b"P2 1 1 9 "]),
       kind=st.sampled_from(["movingai", "image", "yaml"]))
def test_garbage_files_only_raise_scenario_errors(tmp_path_factory, data, prefix, kind):
    d = tmp_path_factory.mktemp("fuzz")
    try:
        if kind == "movingai":
            read_movingai(write(d / "f.map", HEADER.encode()[: len(data) % 40] + data))
        elif kind == "image":
            read_ros(ros_map(d, prefix + data))
        else:
            read_ros(write(d / "g.yaml", ROS_META.format(image="g.pgm").encode()[: len(data) % 120] + data))
    except ScenarioError as e:
        assert "\n" not in str(e)
