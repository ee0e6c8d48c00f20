"""A SLAM map's cells (a map tour): ``scenario.map.coarsen = k``, any map drawn in cells of k of its own a side, no
obstacle lost (a map of 0.05 m cells took only robots below 0.025 m: radius under half a cell); and what the errors
say of a ROS map's unknown cells and of its image given for its YAML."""

from __future__ import annotations

import numpy as np
import pytest

import mrfswarm
from mrfswarm.config import from_dict
from mrfswarm.errors import ConfigError
from mrfswarm.maps import OccupancyGrid, load_map, save_ros


def slam_map(tmp_path) -> OccupancyGrid:
    """A 0.05 m ROS map of 4 x 3 m: a wall one cell thick at x = 2 m with a 1 m door, an unknown blob, its origin
    off zero."""
    prob = np.zeros((80, 60))
    prob[40, :] = 1.0
    prob[40, 25:45] = 0.0  # the door, y in [1.25, 2.25) m past the origin's corner
    prob[10:12, 50:52] = 0.5  # unknown
    grid = OccupancyGrid(prob, resolution=0.05, origin=(-1.0 + 0.025, 0.5 + 0.025))
    save_ros(grid, tmp_path / "lab.yaml")
    return grid


def test_every_obstacle_of_the_fine_map_is_in_an_obstacle_of_the_coarse_one(tmp_path):
    fine = slam_map(tmp_path)
    spec = {"kind": "ros", "path": "lab.yaml"}
    assert np.array_equal(load_map(spec, tmp_path).prob, fine.prob)
    coarse = load_map({**spec, "coarsen": 4}, tmp_path)
    assert coarse.resolution == pytest.approx(0.2) and coarse.shape == (20, 15)
    lo_f, hi_f = fine.bounds
    lo_c, _ = coarse.bounds
    np.testing.assert_allclose(lo_c, lo_f)  # the same corner
    # every fine cell's centre lies in the coarse cell that holds it, at least as occupied
    centres = np.stack(np.meshgrid(*(fine.origin[a] + 0.05 * np.arange(n) for a, n in enumerate(fine.shape)),
                                   indexing="ij"), axis=-1).reshape(-1, 2)
    cells = coarse.world_to_cell(centres)
    assert (coarse.prob[tuple(cells.T)] >= fine.prob.reshape(-1)).all()
    assert coarse.occupied.sum() < 4 * fine.occupied.sum()  # the wall stays a wall one coarse cell thick
    door = coarse.free[10]  # the wall's column: fine cells 25..44 open, so coarse cells 7..10 (6 and 11 hold wall)
    assert door.sum() == 4 and door[7:11].all()  # 1 m narrowed to 0.8: the free space only shrinks


def test_a_block_past_the_map_s_edge_is_a_wall():
    g = load_map({"kind": "free", "size": [10, 7], "coarsen": 3})
    assert g.shape == (4, 3)
    np.testing.assert_array_equal(g.occupied[3], True)  # cells 9..11 of x: 10 and 11 off the map
    np.testing.assert_array_equal(g.occupied[:, 2], True)  # cells 6..8 of y: 7 and 8 off the map
    assert g.free[:3, :2].all()
    assert g.origin == pytest.approx((1.0, 1.0))  # the centre of cells 0..2


def test_voxels_are_coarsened_on_every_axis():
    g = load_map({"kind": "boxes", "size": [8, 8, 4], "boxes": [{"center": [1.5, 2.5, 1.0], "size": [0.5, 0.5, 0.5]}],
                  "coarsen": 2, "resolution": 0.5})
    assert g.shape == (4, 4, 2) and g.resolution == 1.0
    assert np.argwhere(g.occupied).tolist() == [[1, 2, 1]]


@pytest.mark.parametrize("value", [0, -2, 1.5, "2", True, None])
def test_a_wrong_factor_is_one_line_naming_it(value):
    with pytest.raises(ConfigError, match=r"scenario\.map\.coarsen = ") as e:
        load_map({"kind": "free", "size": [10, 10], "coarsen": value})
    assert "\n" not in str(e.value)


def test_a_slam_map_plans_robots_of_0_1_m_once_coarsened(tmp_path):
    """Refused on the 0.05 m cells (radius under half a cell); planned through the door on 0.2 m cells."""
    slam_map(tmp_path)
    scn = {"map": {"kind": "ros", "path": str(tmp_path / "lab.yaml")}, "robot_radius": 0.08, "goal_radius": 0.4,
           "start": {"positions": [[-0.5, 1.9], [-0.5, 2.3]]}, "goal": [2.5, 2.1]}
    with pytest.raises(ConfigError, match=r"0\.025 m on this map; scenario\.map\.coarsen = 4 draws it in 0\.2 m"):
        mrfswarm.plan(from_dict({"scenario": scn, "simulation": {"enabled": False}}), progress=False)
    scn["map"]["coarsen"] = 4
    r = mrfswarm.plan(from_dict({"scenario": scn, "simulation": {"enabled": False}}), progress=False)
    assert r.metrics.reached_goal and r.continuous.certificate.ok


def test_a_start_or_goal_in_a_cell_the_map_leaves_unknown_says_so(tmp_path):
    """ROS grey 205 (P = 0.5) is an obstacle; a start there read "inside an obstacle" (a map tour)."""
    from mrfswarm.errors import ScenarioError

    slam_map(tmp_path)  # unknown at cells (10..11, 50..51): x -0.475 .. -0.425, y 3.0 .. 3.05
    scn = {"map": {"kind": "ros", "path": str(tmp_path / "lab.yaml")}, "robot_radius": 0.02,
           "start": {"positions": [[-0.45, 3.02], [-0.5, 2.3]]}, "goal": [2.5, 2.1]}
    with pytest.raises(ScenarioError, match=r"robot 0 at \(-0\.45, 3\.02\) is inside a cell the map leaves unknown "
                                            r"\(an obstacle\)"):
        mrfswarm.plan(from_dict({"scenario": scn, "simulation": {"enabled": False}}), progress=False)
    scn = {**scn, "start": {"positions": [[-0.5, 2.3], [-0.5, 1.9]]}, "goal": [-0.45, 3.02]}
    with pytest.raises(ScenarioError, match=r"scenario\.goal \(-0\.45, 3\.02\) is inside a cell the map leaves unknown"):
        mrfswarm.plan(from_dict({"scenario": scn, "simulation": {"enabled": False}}), progress=False)
    scn = {**scn, "goal": [1.025, 1.0]}  # the wall at x = 1.0 .. 1.05, below its door
    with pytest.raises(ScenarioError, match=r"scenario\.goal \(1\.025, 1\) is inside an obstacle"):
        mrfswarm.plan(from_dict({"scenario": scn, "simulation": {"enabled": False}}), progress=False)


def test_a_ros_map_given_by_its_image_says_to_give_the_yaml(tmp_path):
    """``kind = "ros"`` pointed at the PGM said only "not a UTF-8 text file ... expected ROS map YAML" (a map tour)."""
    from mrfswarm.errors import ScenarioError

    slam_map(tmp_path)
    with pytest.raises(ScenarioError, match=r"lab\.pgm: not a UTF-8 text file .* \(this is its image: give "
                                            r"scenario\.map\.path the map's \.yaml"):
        load_map({"kind": "ros", "path": "lab.pgm"}, tmp_path)


def test_a_map_too_big_for_the_machine_is_refused_naming_the_coarsening(monkeypatch):
    """The cell limit (10^8) allows maps whose goal field needs some 60 GB: such a run was killed by the system
    without a word (a map tour). Here the machine is said to have 1 MB: a 100 x 100 map needs about 6 MB."""
    import mrfswarm.scenario as scenario_mod
    from mrfswarm.errors import ScenarioError
    from mrfswarm.scenario import build_scenario

    data = {"scenario": {"map": {"kind": "free", "size": [100, 100]}, "goal": [90, 90],
                         "start": {"positions": [[5, 5], [5, 8]]}}, "simulation": {"enabled": False}}
    monkeypatch.setattr(scenario_mod, "machine_memory", lambda: 10**6)
    with pytest.raises(ScenarioError, match=r"^scenario\.map: 100 x 100 cells need about 0.006 GB to plan on \(about 600 "
                                            r"bytes a cell\), more than this machine's 0.001 GB: draw it in coarser cells "
                                            r"\(scenario\.map\.coarsen = 3 or more\) or crop it$"):
        build_scenario(from_dict(data))
    data["scenario"]["map"]["coarsen"] = 3
    data["scenario"]["start"]["positions"] = [[5, 5], [5, 11]]
    assert build_scenario(from_dict(data)).grid.shape == (34, 34)  # within the 1 MB
    monkeypatch.setattr(scenario_mod, "machine_memory", lambda: None)  # a system that does not say: no check
    data["scenario"]["map"].pop("coarsen")
    assert build_scenario(from_dict(data)).grid.shape == (100, 100)
