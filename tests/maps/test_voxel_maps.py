"""3-D maps: ``free``/``boxes`` with three sizes, extruded 2-D maps, voxel files (``npy``, ``binvox``)."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mrfswarm.errors import ConfigError, ScenarioError
from mrfswarm.maps import (
    EXTRUDABLE,
    LOADERS,
    OccupancyGrid,
    load_map,
    read_binvox,
    read_npy,
    save_movingai,
    save_ros,
    save_voxels,
)
from mrfswarm.maps.extrusion import extrude


def write(path: Path, content: bytes) -> Path:
    path.write_bytes(content)
    return path


def one_line(excinfo) -> str:
    msg = str(excinfo.value)
    assert "\n" not in msg and msg
    return msg


def boxes3d(size, boxes, **placement):
    return load_map({"kind": "boxes", "size": list(size), "boxes": boxes, **placement}, ".")


def brute_force_boxes(shape, res, origin, boxes) -> np.ndarray:
    """Voxel by voxel: occupied when its centre lies in [center - size/2, center + size/2) on every axis."""
    occ = np.zeros(shape, dtype=bool)
    for ijk in np.ndindex(*shape):
        c = np.asarray(origin) + res * np.asarray(ijk)
        for b in boxes:
            lo = np.asarray(b["center"]) - np.asarray(b["size"]) / 2
            hi = np.asarray(b["center"]) + np.asarray(b["size"]) / 2
            if np.all((c >= lo - 1e-9) & (c < hi - 1e-9)):
                occ[ijk] = True
    return occ


# -- free and boxes in 3-D -------------------------------------------------------------


def test_free_voxel_map():
    g = load_map({"kind": "free", "size": [4, 3, 2]}, ".")
    assert g.shape == (4, 3, 2) and g.ndim == 3 and not g.occupied.any()
    assert g.origin == (0.0, 0.0, 0.0) and g.resolution == 1.0
    g = load_map({"kind": "free", "size": [4, 3, 2], "resolution": 0.5, "origin": [1, 2, 0.25]}, ".")
    lo, hi = g.bounds
    assert np.allclose(lo, [0.75, 1.75, 0.0]) and np.allclose(hi, [2.75, 3.25, 1.0])


def test_a_box_takes_the_voxels_whose_centres_it_holds():
    g = boxes3d([6, 5, 4], [{"center": [2, 2, 1], "size": [2, 2, 2]}])
    # [1, 3) on each axis: centres 1 and 2 in x and y, 0 and 1 in z
    assert {tuple(map(int, c)) for c in np.argwhere(g.occupied)} == {
        (i, j, k) for i in (1, 2) for j in (1, 2) for k in (0, 1)}
    # a box on the voxel edges: [0.5, 2.5) holds centres 1 and 2
    g = boxes3d([6, 5, 4], [{"center": [1.5, 1.5, 2.5], "size": [2, 2, 1]}])
    assert {tuple(map(int, c)) for c in np.argwhere(g.occupied)} == {(i, j, 2) for i in (1, 2) for j in (1, 2)}


@settings(max_examples=60, deadline=None)
@given(shape=st.tuples(st.integers(1, 6), st.integers(1, 5), st.integers(1, 4)),
       res=st.sampled_from([1.0, 0.5, 0.25]),
       origin=st.tuples(*[st.sampled_from([0.0, 0.125, -1.0, 2.5])] * 3),
       raw=st.lists(st.tuples(st.tuples(*[st.floats(-1, 6)] * 3), st.tuples(*[st.floats(0.1, 4)] * 3)),
                    max_size=4))
def test_boxes_match_brute_force_in_3d(shape, res, origin, raw):
    boxes = [{"center": list(c), "size": list(s)} for c, s in raw]
    g = boxes3d(shape, boxes, resolution=res, origin=list(origin))
    assert np.array_equal(g.occupied, brute_force_boxes(shape, res, origin, boxes))


def test_a_cube_off_the_voxel_faces_warns_or_with_fill_overlap_fills_every_voxel_it_overlaps(caplog):
    """A 1.8 m cube centred on voxel (2, 2, 2) of 1 m voxels: by centres that voxel alone, the cube 0.4 m past it on
    every side (a warning naming it); with fill = "overlap" the 27 voxels it overlaps, no warning."""
    cube = [{"center": [2, 2, 2], "size": [1.8, 1.8, 1.8]}]
    g = boxes3d([5, 5, 5], cube)
    assert {tuple(map(int, c)) for c in np.argwhere(g.occupied)} == {(2, 2, 2)}
    (line,) = [r.getMessage() for r in caplog.records if r.name == "mrfswarm.maps.inline"]
    assert line.startswith("scenario.map.boxes[0] (center [2, 2, 2], size [1.8, 1.8, 1.8]) reaches 0.4 m past the "
                           "cells it fills")
    assert 'scenario.map.fill = "overlap"' in line
    caplog.clear()
    g = boxes3d([5, 5, 5], cube, fill="overlap")
    assert {tuple(map(int, c)) for c in np.argwhere(g.occupied)} == {
        (i, j, k) for i in (1, 2, 3) for j in (1, 2, 3) for k in (1, 2, 3)}
    assert not caplog.records
    # a box on the voxel faces fills L / res voxels a side under both fills; the voxels it touches along a face
    # (z layer 3 above [0.5, 2.5), x 0 and 3 beside [0.5, 2.5)) stay free
    for fill in ("centres", "overlap"):
        g = boxes3d([6, 5, 4], [{"center": [1.5, 1.5, 1.5], "size": [2, 2, 2]}], fill=fill, resolution=1.0)
        assert {tuple(map(int, c)) for c in np.argwhere(g.occupied)} == {
            (i, j, k) for i in (1, 2) for j in (1, 2) for k in (1, 2)}, fill
        g = boxes3d([12, 10, 8], [{"center": [0.75, 0.75, 0.5], "size": [1.0, 1.0, 0.5]}], fill=fill, resolution=0.25,
                    origin=[0.125, 0.125, 0.125])  # [0.25, 1.25) x [0.25, 1.25) x [0.25, 0.75): cells 1..4, 1..4, 1..2
        assert g.occupied.sum() == 4 * 4 * 2 and g.occupied[1:5, 1:5, 1:3].all(), fill
    assert not caplog.records


@settings(max_examples=60, deadline=None)
@given(shape=st.tuples(st.integers(1, 6), st.integers(1, 5), st.integers(1, 4)),
       res=st.sampled_from([1.0, 0.5, 0.25, 0.3]),
       origin=st.tuples(*[st.sampled_from([0.0, 0.125, -1.0, 2.5])] * 3),
       raw=st.lists(st.tuples(st.tuples(*[st.floats(-1, 6)] * 3), st.tuples(*[st.floats(0.01, 4)] * 3)),
                    min_size=1, max_size=4),
       seed=st.integers(0, 2**32 - 1))
def test_fill_overlap_leaves_no_point_of_a_box_in_a_free_voxel(shape, res, origin, raw, seed):
    """Independent of the loader: random points of every box land in occupied voxels (or off the map), and every
    occupied voxel's open cube meets some box's (interval arithmetic)."""
    boxes = [{"center": list(c), "size": list(s)} for c, s in raw]
    g = boxes3d(shape, boxes, resolution=res, origin=list(origin), fill="overlap")
    lo = np.array([b["center"] for b in boxes]) - np.array([b["size"] for b in boxes]) / 2
    hi = lo + np.array([b["size"] for b in boxes])
    pts = np.random.default_rng(seed).uniform(lo[:, None, :], hi[:, None, :], size=(len(boxes), 200, 3)).reshape(-1, 3)
    pts = np.concatenate([pts, lo + 1e-6 * res, hi - 1e-6 * res, (lo + hi) / 2])  # corners just inside, centres
    ijk = np.floor((pts - np.array(origin)) / res + 0.5).astype(int)
    on = (ijk >= 0).all(axis=1) & (ijk < np.array(shape)).all(axis=1)
    assert g.occupied[tuple(ijk[on].T)].all()
    for ijk_occ in np.argwhere(g.occupied):
        c_lo = np.array(origin) + res * ijk_occ - res / 2
        assert ((c_lo + res > lo) & (c_lo < hi)).all(axis=1).any(), ijk_occ


def test_full_height_boxes_are_the_plan_extruded():
    plan = {"kind": "boxes", "size": [8, 6], "boxes": [{"center": [2.5, 2, ], "size": [2, 3]},
                                                       {"center": [6, 4.5], "size": [1, 3]}]}
    flat = load_map(plan, ".")
    tall = boxes3d([8, 6, 3], [{"center": [*b["center"], 1], "size": [*b["size"], 3]} for b in plan["boxes"]])
    assert np.array_equal(tall.occupied, np.repeat(flat.occupied[:, :, None], 3, axis=2))
    assert load_map({**plan, "extrude": 3}, ".") == tall


@pytest.mark.parametrize("spec, match", [
    ({"kind": "free", "size": [3, 3, 3, 3]}, r"scenario\.map\.size = \[3, 3, 3, 3\]: must be a list of 2 integers "
     r"\[W, H\] or 3 \[W, H, D\]"),
    ({"kind": "free", "size": [3, 3, 0]}, r"size\[2\] = 0: must be >= 1"),
    ({"kind": "free", "size": [3, 3, 2.0]}, r"size\[2\] = 2\.0: must be an integer"),
    ({"kind": "free", "size": [1000, 1000, 1000]}, r"1000000000 cells exceeds"),
    ({"kind": "free", "size": [3, 3, 3], "origin": [0, 0]}, r"origin = \[0, 0\]: must be a list of 3 numbers "
     r"\[x, y, z\] on a 3-D map"),
    ({"kind": "free", "size": [3, 3], "origin": [0, 0, 0]}, r"origin = \[0, 0, 0\]: must be a list of 2 numbers "
     r"\[x, y\]$"),
    ({"kind": "free", "size": [3, 3, 3], "origin": [0, 0, "z"]}, r"origin\[2\] = 'z'"),
    ({"kind": "boxes", "size": [3, 3, 3], "boxes": [{"center": [1, 1], "size": [1, 1, 1]}]},
     r"boxes\[0\]\.center = \[1, 1\]: must be a list of 3 numbers \[x, y, z\] on a 3-D map"),
    ({"kind": "boxes", "size": [3, 3, 3], "boxes": [{"center": [1, 1, 1], "size": [1, 1]}]},
     r"boxes\[0\]\.size = \[1, 1\]: must be a list of 3 numbers \[lx, ly, lz\] \(metres\) on a 3-D map"),
    ({"kind": "boxes", "size": [3, 3], "boxes": [{"center": [1, 1, 1], "size": [1, 1]}]},
     r"boxes\[0\]\.center = \[1, 1, 1\]: must be a list of 2 numbers \[x, y\]$"),
    ({"kind": "boxes", "size": [3, 3, 3], "boxes": [{"center": [1, 1, 1], "size": [1, 1, 0]}]},
     r"boxes\[0\]\.size\[2\] = 0: must be > 0"),
    ({"kind": "boxes", "size": [3, 3, 3], "boxes": [3]}, r"boxes\[0\] = 3: must be a table \{center=\[x, y, z\]"),
])
def test_bad_3d_tables_are_one_line_config_errors(spec, match):
    with pytest.raises(ConfigError, match=match) as e:
        load_map(spec, ".")
    one_line(e)


def test_box_outside_a_voxel_map_warns(caplog):
    boxes3d([4, 4, 2], [{"center": [1, 1, 9], "size": [1, 1, 1]}])
    assert "boxes[0] (center [1, 1, 9], size [1, 1, 1]) overlaps no cell of the 4 x 4 x 2 map" in caplog.text


# -- extrusion ---------------------------------------------------------------------------


def two_d_maps(tmp_path: Path) -> dict[str, dict]:
    occ = np.zeros((5, 4), dtype=bool)
    occ[1, 2] = occ[3, 0] = True
    save_movingai(OccupancyGrid.from_occupied(occ), tmp_path / "m.map")
    save_ros(OccupancyGrid.from_occupied(occ), tmp_path / "m.yaml")
    return {
        "free": {"kind": "free", "size": [5, 4]},
        "boxes": {"kind": "boxes", "size": [5, 4], "boxes": [{"center": [1, 2], "size": [1, 1]}]},
        "ascii": {"kind": "ascii", "rows": ["...#.", ".....", ".#...", "....."]},
        "movingai": {"kind": "movingai", "path": "m.map"},
        "ros": {"kind": "ros", "path": "m.yaml"},
    }


def test_every_2d_kind_extrudes(tmp_path):
    maps = two_d_maps(tmp_path)
    assert set(maps) == set(EXTRUDABLE)
    for kind, spec in maps.items():
        flat = load_map(spec, tmp_path)
        tall = load_map({**spec, "extrude": 4}, tmp_path)
        assert tall.shape == (*flat.shape, 4), kind
        assert np.array_equal(tall.prob, np.repeat(flat.prob[:, :, None], 4, axis=2)), kind
        assert tall.origin == (*flat.origin, 0.0) and tall.resolution == flat.resolution, kind


def test_extruded_origin_places_the_layers():
    spec = {"kind": "ascii", "rows": ["..", "#."], "resolution": 0.5, "origin": [1.0, 2.0, 0.25], "extrude": 3}
    g = load_map(spec, ".")
    assert g.origin == (1.0, 2.0, 0.25)
    assert np.allclose(g.cell_to_world([0, 1, 2]), [1.0, 2.5, 1.25])
    lo, hi = g.bounds
    assert lo[2] == 0.0 and hi[2] == 1.5  # floor at z = 0, ceiling 3 voxels up
    # off the map (below the floor, above the ceiling) is not free: the map's box is the room
    assert not g.is_free(np.array([[0, 0, -1], [0, 0, 3]])).any() and g.is_free(np.array([0, 0, 2]))


def test_ros_extruded_keeps_its_frame_check(tmp_path):
    spec = two_d_maps(tmp_path)["ros"]
    g = load_map({**spec, "origin": [0.0, 0.0, 2.0], "extrude": 2}, tmp_path)
    assert g.origin == (0.0, 0.0, 2.0)
    with pytest.raises(ConfigError, match=r"origin = \[1\.0, 0\.0\] disagrees with the ROS map"):
        load_map({**spec, "origin": [1.0, 0.0, 2.0], "extrude": 2}, tmp_path)


@pytest.mark.parametrize("spec, match", [
    ({"kind": "free", "size": [3, 3], "extrude": 0}, r"scenario\.map\.extrude = 0: must be an integer >= 1"),
    ({"kind": "free", "size": [3, 3], "extrude": 2.5}, r"extrude = 2\.5: must be an integer"),
    ({"kind": "free", "size": [3, 3], "extrude": True}, r"extrude = True: must be an integer"),
    ({"kind": "free", "size": [3, 3, 3], "extrude": 2}, r"extrude = 2: the map is already 3-D \(size = \[3, 3, 3\]\)"),
    ({"kind": "free", "size": [3, 3], "extrude": 2, "origin": [0, 0]},
     r"origin = \[0, 0\]: must be a list of 3 numbers \[x, y, z\] on a 3-D map "
     r"\(scenario\.map\.extrude makes it one: its z is the centre of layer 0\)$"),
    ({"kind": "free", "size": [10000, 10000], "extrude": 2}, r"extrude = 2: 10000 x 10000 x 2 voxels exceeds"),
    ({"kind": "binvox", "path": "v.binvox", "extrude": 2}, r"unknown key scenario\.map\.extrude"),
])
def test_bad_extrusion_is_a_config_error(spec, match):
    with pytest.raises(ConfigError, match=match) as e:
        load_map(spec, ".")
    one_line(e)


def test_extrude_refuses_a_voxel_grid():
    with pytest.raises(ConfigError, match=r"already 3-D \(2 x 2 x 2 voxels\)"):
        extrude(OccupancyGrid(np.zeros((2, 2, 2))), 3)


# -- voxel files -------------------------------------------------------------------------


def some_voxels(shape=(5, 4, 3)) -> np.ndarray:
    occ = np.zeros(shape, dtype=bool)
    occ[1, 2, 0] = occ[4, 0, 2] = occ[0, 3, 1] = True
    return occ


def test_npy_round_trip_and_placement(tmp_path):
    occ = some_voxels()
    save_voxels(OccupancyGrid.from_occupied(occ), tmp_path / "v.npy")
    g = load_map({"kind": "npy", "path": "v.npy", "resolution": 0.5, "origin": [1, 1, 0.25]}, tmp_path)
    assert np.array_equal(g.occupied, occ) and g.resolution == 0.5 and g.origin == (1.0, 1.0, 0.25)
    assert load_map({"kind": "npy", "path": "v.npy"}, tmp_path).origin == (0.0, 0.0, 0.0)


def test_npy_of_probabilities(tmp_path):
    prob = np.zeros((2, 2, 2))
    prob[1, 1, 1], prob[0, 1, 0] = 0.5, 0.3  # 0.5 is an obstacle (the occupancy threshold)
    np.save(tmp_path / "p.npy", prob.astype(np.float32))
    g = read_npy(tmp_path / "p.npy")
    assert np.allclose(g.prob, prob) and {tuple(map(int, c)) for c in np.argwhere(g.occupied)} == {(1, 1, 1)}


def binvox_bytes_by_the_spec(occ: np.ndarray) -> bytes:
    """A binvox file written from its specification (independent of trimesh): y runs fastest, then z, then x."""
    d = occ.shape[0]
    flat = occ.transpose(0, 2, 1).ravel().astype(np.uint8)  # order (x, z, y)
    runs = bytearray()
    i = 0
    while i < len(flat):
        j = i
        while j < len(flat) and flat[j] == flat[i] and j - i < 255:
            j += 1
        runs += bytes([flat[i], j - i])
        i = j
    return f"#binvox 1\ndim {d} {d} {d}\ntranslate 0 0 0\nscale 1\ndata\n".encode() + bytes(runs)


def test_binvox_reads_the_specified_axis_order(tmp_path):
    occ = some_voxels((6, 6, 6))
    occ[5, 5, :] = True  # a column: 6 voxels along z
    write(tmp_path / "v.binvox", binvox_bytes_by_the_spec(occ))
    g = load_map({"kind": "binvox", "path": "v.binvox", "resolution": 0.25}, tmp_path)
    assert np.array_equal(g.occupied, occ) and g.resolution == 0.25


def test_binvox_round_trip_through_trimesh(tmp_path):
    occ = np.random.default_rng(3).random((7, 7, 7)) < 0.3
    save_voxels(OccupancyGrid.from_occupied(occ), tmp_path / "v.binvox")
    assert np.array_equal(read_binvox(tmp_path / "v.binvox").occupied, occ)
    # trimesh's runs are the specification's
    written = (tmp_path / "v.binvox").read_bytes()
    assert written.split(b"data\n", 1)[1] == binvox_bytes_by_the_spec(occ).split(b"data\n", 1)[1]
    # one voxel: trimesh's transform divides by d - 1 = 0, which must stay quiet
    save_voxels(OccupancyGrid.from_occupied(np.ones((1, 1, 1), dtype=bool)), tmp_path / "one.binvox")
    assert read_binvox(tmp_path / "one.binvox").occupied.all()


def npy_bytes(a: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.save(buf, a, allow_pickle=True)
    return buf.getvalue()


@pytest.mark.parametrize("name, content, match", [
    ("v.npy", npy_bytes(np.zeros((2, 2, 2), dtype=np.int64)), r"dtype int64: expected bool"),
    ("v.npy", npy_bytes(np.zeros((2, 2, 2, 2), dtype=bool)),
     r"shape \(2, 2, 2, 2\): expected a map \(W, H\) or a voxel map \(W, H, D\)"),
    ("v.npy", npy_bytes(np.zeros(4, dtype=bool)), r"shape \(4,\): expected a map \(W, H\) or a voxel map"),
    ("v.npy", npy_bytes(np.zeros((2, 2, 0), dtype=bool)), r"must have shape"),
    ("v.npy", npy_bytes(np.full((2, 2, 2), 1.5)), r"prob\[0, 0, 0\] = 1\.5 is not in \[0, 1\]"),
    ("v.npy", npy_bytes(np.array([{"a": 1}], dtype=object)), r"not a NumPy \.npy array"),
    ("v.npy", b"\x93NUMPY garbage", r"not a NumPy \.npy array"),
    ("v.npy", npy_bytes(np.zeros((4, 4, 4), dtype=bool))[:-10], r"not a NumPy \.npy array"),
    ("v.binvox", b"#binvox 1\ndim 4 3 2\ntranslate 0 0 0\nscale 1\ndata\n\x00\x18",
     r"binvox dim 4 3 2: expected a cube"),
    ("v.binvox", b"#binvox 1\ndim 2 2 2\ntranslate 0 0 0\nscale 1\ndata\n\x00\x07",
     r"binvox data holds 7 voxels in 2 bytes of \(value, count\) pairs, expected 8"),
    ("v.binvox", b"#binvox 1\ndim 2 2 2\ntranslate 0 0 0\nscale 1\ndata\n\x00\x08\x01",
     r"binvox data holds 8 voxels in 3 bytes"),
    ("v.binvox", b"#binvox 1\ndim 2 2\ndata\n", r"binvox dim 2 2: expected a cube|not a binvox file"),
    ("v.binvox", b"solid cube\n", r"not a binvox file"),
])
def test_bad_voxel_files_are_one_line_scenario_errors(tmp_path, name, content, match):
    p = write(tmp_path / name, content)
    with pytest.raises(ScenarioError, match=match) as e:
        load_map({"kind": name.split(".")[1], "path": name}, tmp_path)
    assert str(p) in one_line(e)


def test_missing_voxel_files(tmp_path):
    for kind in ("npy", "binvox"):
        what = "map" if kind == "npy" else "voxel"  # a .npy file holds a 2-D map or voxels
        with pytest.raises(ScenarioError, match=rf"cannot read {what} file .*nope\.{kind}.*No such file") as e:
            load_map({"kind": kind, "path": f"nope.{kind}"}, tmp_path)
        one_line(e)


@pytest.mark.parametrize("spec, match", [
    ({"kind": "npy"}, r"scenario\.map\.path is missing"),
    ({"kind": "binvox", "path": "v.binvox", "origin": [0, 0]}, r"origin = \[0, 0\]: must be a list of 3 numbers"),
    ({"kind": "npy", "path": "v.npy", "resolution": -1}, r"resolution = -1: must be > 0"),  # before the file
    ({"kind": "binvox", "path": "v.binvox", "resolution": 0}, r"resolution = 0: must be > 0"),
    ({"kind": "binvox", "path": 7}, r"path = 7"),
])
def test_bad_voxel_tables_are_config_errors(spec, match):
    with pytest.raises(ConfigError, match=match) as e:
        load_map(spec, ".")
    one_line(e)


def test_save_voxels_refusals(tmp_path):
    with pytest.raises(ScenarioError, match="a voxel file holds a 3-D grid"):
        save_voxels(OccupancyGrid(np.zeros((2, 2))), tmp_path / "x.npy")
    with pytest.raises(ScenarioError, match=r"suffix must be \.npy or \.binvox"):
        save_voxels(OccupancyGrid(np.zeros((2, 2, 2))), tmp_path / "x.vox")
    with pytest.raises(ScenarioError, match=r"binvox holds cubes .* got 2 x 2 x 3; save it as \.npy"):
        save_voxels(OccupancyGrid(np.zeros((2, 2, 3))), tmp_path / "x.binvox")
    with pytest.raises(ScenarioError, match="cannot write voxel file"):
        save_voxels(OccupancyGrid(np.zeros((2, 2, 2))), tmp_path / "no_dir" / "x.npy")


def test_the_kinds_are_listed_once():
    assert set(EXTRUDABLE) < set(LOADERS) and {"npy", "binvox"} <= set(LOADERS)
    with pytest.raises(ConfigError, match=r"kind = 'vox': must be one of free, boxes, ascii, movingai, ros, npy, binvox"):
        load_map({"kind": "vox"}, ".")


@settings(deadline=None, max_examples=150, suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(data=st.binary(max_size=80),
       prefix=st.sampled_from([b"", b"\x93NUMPY\x01\x00", npy_bytes(np.zeros((2, 2, 2), bool))[:40],
                               b"#binvox 1\n", b"#binvox 1\ndim 2 2 2\ntranslate 0 0 0\nscale 1\ndata\n"]),
       kind=st.sampled_from(["npy", "binvox"]))
def test_garbage_voxel_files_only_raise_scenario_errors(tmp_path_factory, data, prefix, kind):
    d = tmp_path_factory.mktemp("fuzz")
    try:
        write(d / f"f.{kind}", prefix + data)
        load_map({"kind": kind, "path": f"f.{kind}"}, d)
    except ScenarioError as e:
        assert "\n" not in str(e)


def test_binvox_without_trimesh_says_how_to_install(tmp_path, monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "trimesh", None)  # what `import trimesh` meets when it is not installed
    monkeypatch.setitem(sys.modules, "trimesh.exchange", None)
    with pytest.raises(ScenarioError, match=r"needs trimesh: pip install 'mrfswarm\[voxels\]'") as e:
        read_binvox(write(tmp_path / "v.binvox", b"#binvox 1\n"))
    one_line(e)


def test_a_2d_npy_array_is_a_2d_map(tmp_path):
    """A (W, H) array was refused ("a voxel map is (W, H, D)"): a library tour saved its 2-D map so and could not
    load it. It is the 2-D map of the same cells, placed by resolution and a 2-number origin."""
    occ = np.zeros((6, 4), dtype=bool)
    occ[2, 1:3] = True
    np.save(tmp_path / "flat.npy", occ)
    g = load_map({"kind": "npy", "path": "flat.npy", "resolution": 0.5, "origin": [1.0, 2.0]}, tmp_path)
    assert g.ndim == 2 and np.array_equal(g.occupied, occ) and tuple(g.origin) == (1.0, 2.0) and g.resolution == 0.5
    assert tuple(load_map({"kind": "npy", "path": "flat.npy"}, tmp_path).origin) == (0.0, 0.0)
    with pytest.raises(ConfigError, match=r"origin = \[1, 2, 3\]: must be a list of 2 numbers"):
        load_map({"kind": "npy", "path": "flat.npy", "origin": [1, 2, 3]}, tmp_path)


@pytest.mark.parametrize("shape", [(5,), (2, 2, 2, 2)], ids=["1-D", "4-D"])
def test_an_npy_array_of_other_axes_is_named_before_the_origin(tmp_path, shape):
    """A 1-D or 4-D array with an origin of 2 numbers was refused as "origin ... must be a list of 3 numbers
    [x, y, z] on a 3-D map" (a map tour): the map is neither, the file is wrong. The array's shape is said."""
    np.save(tmp_path / "odd.npy", np.zeros(shape, dtype=bool))
    with pytest.raises(ScenarioError, match=r"odd\.npy: array of shape .*: expected a map \(W, H\) or a voxel map"):
        load_map({"kind": "npy", "path": "odd.npy", "origin": [0.0, 0.0]}, tmp_path)


def test_a_2d_npy_array_extrudes_as_every_2d_map(tmp_path):
    """A (W, H) array is a 2-D map, and "a 2-D map of any kind takes extrude" (the docs), but the npy loader refused
    the key as unknown (a map tour). It is the 2-D map raised, placed as the other kinds' are; a (W, H, D) array
    given extrude is refused as already 3-D."""
    occ = np.zeros((6, 4), dtype=bool)
    occ[2, 1:3] = True
    np.save(tmp_path / "flat.npy", occ)
    g = load_map({"kind": "npy", "path": "flat.npy", "resolution": 0.5, "origin": [1.0, 2.0, 0.25],
                  "extrude": 3}, tmp_path)
    assert g.shape == (6, 4, 3) and g.origin == (1.0, 2.0, 0.25) and g.resolution == 0.5
    assert all(np.array_equal(g.occupied[:, :, k], occ) for k in range(3))
    assert load_map({"kind": "npy", "path": "flat.npy", "extrude": 2}, tmp_path).origin == (0.0, 0.0, 0.0)
    with pytest.raises(ConfigError, match=r"origin = \[1\.0, 2\.0\]: must be a list of 3 numbers"):
        load_map({"kind": "npy", "path": "flat.npy", "origin": [1.0, 2.0], "extrude": 2}, tmp_path)
    with pytest.raises(ConfigError, match=r"extrude = 0: must be an integer >= 1"):
        load_map({"kind": "npy", "path": "flat.npy", "extrude": 0}, tmp_path)
    np.save(tmp_path / "tall.npy", np.zeros((3, 3, 2), dtype=bool))
    with pytest.raises(ConfigError, match=r"extrude = 2: the map is already 3-D \(3 x 3 x 2 voxels\)"):
        load_map({"kind": "npy", "path": "tall.npy", "extrude": 2}, tmp_path)
