"""Start swarms and the goal on maps of 2 and 3 axes (mrfswarm.discrete.start, mrfswarm.scenario.goal_cell)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mrfswarm.discrete.start import start_cells
from mrfswarm.errors import ConfigError, ScenarioError
from mrfswarm.geometry import downwash_scale
from mrfswarm.maps import OccupancyGrid, load_map
from mrfswarm.scenario import goal_cell

ROOM = {"kind": "boxes", "size": [10, 8, 5], "boxes": [{"center": [4.5, 3.5, 1.5], "size": [2, 2, 2]}]}  # voxels 4-5, 3-4, 1-2


def room() -> OccupancyGrid:
    return load_map(ROOM, ".")


def one_line(excinfo) -> str:
    msg = str(excinfo.value)
    assert "\n" not in msg and msg
    return msg


def sequential_draws(spec: dict, grid: OccupancyGrid, seed: int, downwash: float = 1.0) -> np.ndarray:
    """The paper's sampling, one draw at a time: N(center, sigma^2 I) in batches of N; a draw is kept when its
    cell is free and one cell (downwash-scaled) from every robot placed and every earlier free draw of its batch
    that was so (in the plane: on a cell nobody took). The reference the vectorized sampler must match."""
    rng = np.random.default_rng(seed)
    c = np.asarray(spec["center"], dtype=float)
    scale = downwash_scale(grid.ndim, downwash)
    n, cells = spec["n_robots"], []
    while len(cells) < n:
        valid: list[np.ndarray] = []  # this batch's draws clear of the robots placed before it
        kept = []
        for cell in grid.world_to_cell(rng.normal(c, spec["sigma"], size=(n, grid.ndim))):
            if not grid.is_free(cell) or any(np.linalg.norm((cell - q) * scale) < 1 - 1e-9 for q in cells):
                continue
            if not any(np.linalg.norm((cell - q) * scale) < 1 - 1e-9 for q in valid):
                kept.append(cell)
            valid.append(cell)
        cells += kept[:n - len(cells)]
    return np.array(cells)


def scaled_gaps(cells: np.ndarray, downwash: float) -> np.ndarray:
    x = cells * downwash_scale(cells.shape[1], downwash)
    d = np.linalg.norm(x[:, None] - x[None], axis=-1)
    return d[np.triu_indices(len(x), 1)]


# -- explicit positions ------------------------------------------------------------------


def test_positions_in_3d_snap_to_their_voxels():
    cells = start_cells({"positions": [[0, 0, 0], [1.4, 2.6, 3.2], [9, 7, 4]]}, room())
    assert cells.tolist() == [[0, 0, 0], [1, 3, 3], [9, 7, 4]] and cells.dtype == np.intp


def test_positions_and_a_goal_off_their_cell_centres_are_said(caplog):
    """Explicit positions and the goal are moved to their cells' centres, up to half a cell; that was silent (a robot
    placed 0.5 m off "started" elsewhere). One warning line each, naming the largest move; none at the centres."""
    with caplog.at_level("WARNING"):
        start_cells({"positions": [[0, 0, 0], [1.4, 2.6, 3.2], [9, 7, 4]]}, room())
        goal_cell((8.0, 6.0, 3.0), room())
    assert caplog.messages == ["scenario.start.positions: placed at cell centres, 1 of 3 moved, the most robot 1 by "
                               "0.6 m: (1.4, 2.6, 3.2) -> (1, 3, 3)"]
    caplog.clear()
    with caplog.at_level("WARNING"):
        goal_cell((7.6, 6.0, 3.0), room())
        start_cells({"positions": [[0, 0, 0], [9, 7, 4]]}, room())
    assert caplog.messages == ["scenario.goal: placed at its cell's centre, 0.4 m away: (7.6, 6, 3) -> (8, 6, 3)"]


@pytest.mark.parametrize("positions, match", [
    ([[1, 1, 1], [5, 4, 2]], r"^scenario\.start\.positions\[1\]: robot 1 at \(5, 4, 2\) is inside an obstacle "
                             r"\(cell \(5, 4, 2\)\)$"),
    ([[1, 1, 1], [1, 1, 5]], r"^scenario\.start\.positions\[1\]: robot 1 at \(1, 1, 5\) is off the map \(x in "
                             r"\[-0\.5, 9\.5\), y in \[-0\.5, 7\.5\), z in \[-0\.5, 4\.5\)\)$"),
    ([[1, 1, -0.6]], r"^scenario\.start\.positions\[0\]: robot 0 at \(1, 1, -0\.6\) is off the map"),
    ([[1, 1, 1], [2, 2, 2], [1.2, 0.9, 1.3]], r"^scenario\.start\.positions: robots 0 and 2 are both in cell "
                                              r"\(1, 1, 1\) \(at \(1, 1, 1\) and \(1\.2, 0\.9, 1\.3\)\)$"),
])
def test_bad_3d_positions_name_the_robot(positions, match):
    with pytest.raises(ScenarioError, match=match) as e:
        start_cells({"positions": positions}, room())
    one_line(e)


@pytest.mark.parametrize("spec, grid, match", [
    ({"positions": [[1, 1, 1], [2, 2]]}, "3d", r"^scenario\.start\.positions\[1\] = \[2, 2\]: 2 coordinates on a 3-D map, "
                                              r"give \[x, y, z\]$"),
    ({"positions": [[1, 1, 1]]}, "2d", r"^scenario\.start\.positions\[0\] = \[1, 1, 1\]: 3 coordinates on a 2-D map, "
                                       r"give \[x, y\]$"),
    ({"positions": []}, "3d", r"scenario\.start\.positions must be a list of \[x, y, z\] points, got \[\]"),
    ({"positions": [[1, "a", 1]]}, "3d", r"must be a list of \[x, y, z\] points"),
    ({"positions": [[1, 1, float("nan")]]}, "3d", r"must be finite"),
    ({"center": [1, 1], "n_robots": 3}, "3d", r"^scenario\.start\.center = \[1, 1\]: 2 coordinates on a 3-D map, "
                                              r"give \[x, y, z\]$"),
    ({"center": [1, 1, 1], "n_robots": 3}, "2d", r"scenario\.start\.center = \[1, 1, 1\]: 3 coordinates on a 2-D map"),
    ({"center": [1, 1, "z"], "n_robots": 3}, "3d", r"scenario\.start\.center must be \[x, y, z\], got \[1, 1, 'z'\]"),
    # was "world_to_cell: points must be finite", naming neither the key nor the value
    ({"center": [float("nan"), 1], "n_robots": 3}, "2d", r"^scenario\.start\.center must be finite, got \[nan, 1\]$"),
])
def test_points_with_the_wrong_number_of_coordinates(spec, grid, match):
    g = room() if grid == "3d" else load_map({"kind": "free", "size": [5, 5]}, ".")
    with pytest.raises(ConfigError, match=match) as e:
        start_cells(spec, g)
    one_line(e)


def test_a_centre_off_the_voxel_map():
    with pytest.raises(ScenarioError, match=r"scenario\.start\.center \(1, 1, 9\) is off the map \(.*z in "
                                            r"\[-0\.5, 4\.5\)\)"):
        start_cells({"center": [1, 1, 9], "n_robots": 3}, room())


# -- sampled swarms ----------------------------------------------------------------------


def test_sampled_swarm_in_3d():
    g = room()
    spec = {"center": [5, 4, 2], "n_robots": 30, "sigma": 2.0, "seed": 4}  # the centre is inside the box
    cells = start_cells(spec, g)
    assert cells.shape == (30, 3)
    assert g.is_free(cells).all()
    assert len({tuple(c) for c in cells.tolist()}) == 30
    assert len(np.unique(cells[:, 2])) > 1  # spread in z too
    assert np.array_equal(start_cells(spec, g), cells)  # deterministic in the seed
    assert not np.array_equal(start_cells(spec, g, seed=5), cells)  # --seed overrides the table's


@settings(max_examples=80, deadline=None)
@given(d=st.sampled_from([2, 3]), seed=st.integers(0, 2**16), n=st.integers(1, 25), sigma=st.floats(0.3, 5.0),
       density=st.floats(0.0, 0.5), cx=st.floats(0, 1), cy=st.floats(0, 1), cz=st.floats(0, 1),
       downwash=st.sampled_from([1.0, 1.5, 2.0, 3.0]))
def test_sampler_matches_the_sequential_draws(d, seed, n, sigma, density, cx, cy, cz, downwash):
    shape = (9, 7, 4)[:d]
    occ = np.random.default_rng(seed + 1).random(shape) < density
    g = OccupancyGrid.from_occupied(occ)
    if n > int(g.free.sum()):
        return
    center = [cx * (shape[0] - 1), cy * (shape[1] - 1), cz * (shape[-1] - 1)][:d]
    spec = {"center": center, "n_robots": n, "sigma": sigma}
    try:
        cells = start_cells(spec, g, seed, downwash=downwash)
    except ScenarioError as e:  # too few free cells near the centre: the draw budget ran out
        assert "could not place" in str(e)
        return
    assert np.array_equal(cells, sequential_draws(spec, g, seed, downwash))
    assert scaled_gaps(cells, downwash).min(initial=1.0) >= 1.0 - 1e-9


def test_sampled_swarm_keeps_the_downwash():
    g = room()
    spec = {"center": [2, 4, 2], "n_robots": 20, "sigma": 1.5, "seed": 1}
    plain = start_cells(spec, g)
    assert scaled_gaps(plain, 2.0).min() < 1.0  # without the downwash some robots stand on others
    cells = start_cells(spec, g, downwash=2.0)
    assert g.is_free(cells).all() and scaled_gaps(cells, 2.0).min() >= 1.0 - 1e-9
    columns = cells[:, :2].tolist()
    stacked = [i for i, c in enumerate(columns) if columns.count(c) > 1]
    assert stacked  # robots still share columns, two voxels apart
    assert np.array_equal(start_cells({"center": [2, 4], "n_robots": 8, "sigma": 1.5}, load_map(
        {"kind": "free", "size": [10, 8]}, "."), downwash=3.0), start_cells(
        {"center": [2, 4], "n_robots": 8, "sigma": 1.5}, load_map({"kind": "free", "size": [10, 8]}, ".")))


def test_explicit_positions_keep_the_downwash():
    assert start_cells({"positions": [[1, 1, 0], [1, 1, 2], [2, 1, 1]]}, room(), downwash=2.0).shape == (3, 3)
    with pytest.raises(ScenarioError, match=r"^scenario\.start\.positions: robots 0 and 1 are in cells \(1, 1, 0\) and "
                                            r"\(1, 1, 1\), 1 apart in z: scenario\.downwash = 2 needs 2 "
                                            r"\(at \(1, 1, 0\) and \(1, 1, 1\)\)$") as e:
        start_cells({"positions": [[1, 1, 0], [1, 1, 1]]}, room(), downwash=2.0)
    one_line(e)
    with pytest.raises(ScenarioError, match=r"robots 1 and 2 are in cells \(1, 1, 3\) and \(1, 1, 1\), 2 apart in z: "
                                            r"scenario\.downwash = 2\.5 needs 3"):
        start_cells({"positions": [[5, 5, 3], [1, 1, 3], [1, 1, 1]]}, room(), downwash=2.5)
    start_cells({"positions": [[1, 1, 0], [1, 1, 1]]}, room())  # one voxel apart is enough without a downwash


# -- the goal ----------------------------------------------------------------------------


def test_goal_cell_in_3d():
    assert goal_cell((8.2, 6.9, 3.6), room()).tolist() == [8, 7, 4]


@pytest.mark.parametrize("goal, grid, error, match", [
    # the wrong number of coordinates: a ConfigError, as for a start position
    ((8.0, 6.0), "3d", ConfigError, r"^scenario\.goal = \[8\.0, 6\.0\]: 2 coordinates on a 3-D map, give \[x, y, z\]$"),
    ((1.0, 2.0, 3.0), "2d", ConfigError,
     r"^scenario\.goal = \[1\.0, 2\.0, 3\.0\]: 3 coordinates on a 2-D map, give \[x, y\]$"),
    ((5.0, 4.0, 1.0), "3d", ScenarioError, r"^scenario\.goal \(5, 4, 1\) is inside an obstacle \(cell \(5, 4, 1\)\)$"),
    ((5.0, 4.0, 5.0), "3d", ScenarioError,
     r"^scenario\.goal \(5, 4, 5\) is off the map \(x in .*, z in \[-0\.5, 4\.5\)\)$"),
    ((-1.0, 2.0), "2d", ScenarioError, r"^scenario\.goal \(-1, 2\) is off the map \(x in \[-0\.5, .*\)\)$"),
])
def test_bad_goals_name_the_value(goal, grid, error, match):
    g = room() if grid == "3d" else load_map({"kind": "free", "size": [5, 5]}, ".")
    with pytest.raises(error, match=match) as e:
        goal_cell(goal, g)
    one_line(e)
