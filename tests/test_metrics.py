"""The discrete metrics (:mod:`mrfswarm.metrics`), on hand-checked cases."""

import numpy as np
import pytest

from mrfswarm.metrics import discrete_metrics, min_separation, obstacle_clearance


def test_min_separation_includes_moves():
    paths = np.array([[[0, 0], [3, 0]], [[1, 0], [2, 0]]])  # they approach to 1 cell
    assert min_separation(paths) == pytest.approx(1.0)
    paths = np.array([[[0, 0], [2, 0]], [[1, 1], [1, 0]]])  # the distance dips mid-move
    # relative start (-2, 0), relative motion (1,1)-(-1,0) = (2,1): closest approach 2/sqrt(5) < both ends
    assert min_separation(paths) == pytest.approx(2 / np.sqrt(5))


def test_obstacle_clearance_exact():
    occ = np.zeros((10, 10), bool)
    occ[5, 5] = True
    assert obstacle_clearance(occ, np.array([[2.0, 5.0]])) == pytest.approx(2.5)
    assert obstacle_clearance(occ, np.array([[3.5, 3.5]])) == pytest.approx(np.hypot(1, 1))
    # the map's edge is a wall: a point half a cell in from it is half a cell clear, obstacles or not
    assert obstacle_clearance(occ, np.array([[0.0, 5.0]])) == pytest.approx(0.5)
    assert obstacle_clearance(np.zeros((4, 4), bool), np.array([[1.0, 1.0]])) == pytest.approx(1.5)
    assert obstacle_clearance(np.zeros((4, 4, 3), bool), np.array([[1.5, 1.5, 2.2]])) == pytest.approx(0.3)  # ceiling
    assert obstacle_clearance(occ, np.zeros((0, 2))) is None


def test_discrete_metrics_summary():
    occ = np.zeros((20, 20), bool)
    occ[10, :] = True
    paths = np.array([[[0, 0], [0, 3]], [[1, 0], [1, 3]], [[2, 0], [2, 3]]])
    m = discrete_metrics(paths, occ, resolution=0.5, goal=np.array([2, 1]), goal_radius=1.0)
    assert m.steps == 2
    np.testing.assert_allclose(m.path_lengths, [1.0, 1.0])  # 2 cells of 0.5 m
    np.testing.assert_allclose(m.mean_distance, [1.5, 1.5, 1.5])
    assert m.min_separation == pytest.approx(1.5)
    assert m.min_obstacle_clearance == pytest.approx(0.5 * 0.5)  # robot 0 runs along the map's edge
    inner = discrete_metrics(paths + 4, occ, resolution=0.5)  # in from the edges: the wall at x = 10 is nearest
    assert inner.min_obstacle_clearance == pytest.approx((10 - 6 - 0.5) * 0.5)
    assert m.final_goal_distance == pytest.approx(np.hypot(0, 0.5) * 0.5)
    assert m.reached_goal is True
    far = discrete_metrics(paths, occ, resolution=0.5, goal=np.array([8, 1]), goal_radius=1.0)
    assert far.reached_goal is False  # centroid 3 m away
    # ... unless the plan ended by the arrival rule (every robot in the goal region)
    assert discrete_metrics(paths, occ, 0.5, np.array([8, 1]), 1.0, arrived=True).reached_goal is True
    # a swarm stopped around a goal it cannot reach (four robots in front of the walls of an enclosure): its
    # centroid on the goal, no robot within goal_radius: not reached
    ring = np.array([[[5, 10], [10, 5], [15, 10], [10, 15]]])
    around = discrete_metrics(ring, np.zeros((20, 20), bool), 1.0, np.array([10, 10]), 2.0)
    assert around.final_goal_distance == pytest.approx(0.0) and around.reached_goal is False
    one_in = discrete_metrics(ring.copy() - np.array([[[0, 0]] * 3 + [[0, 4]]]), np.zeros((20, 20), bool), 1.0,
                              np.array([10, 10]), 2.0)
    assert one_in.final_goal_distance == pytest.approx(1.0) and one_in.reached_goal is True


def test_a_big_swarm_that_arrived_reached_the_goal():
    """swarm100 ends by the arrival rule with its centroid off goal_radius; result.json says reached."""
    from mrfswarm.config import load_config
    from mrfswarm.pipeline import plan
    from support.repository import EXPERIMENTS

    r = plan(load_config(EXPERIMENTS / "swarm100.toml", ["smoothing.enabled=false"]), progress=False)
    s = r.summary()
    assert r.discrete.stop_reason == "arrived" and s["robots_at_goal"] == s["n_robots"] == 100
    assert r.metrics.final_goal_distance > r.scenario.goal_radius  # the centroid alone would say no
    assert s["reached_goal"] is True


def test_robots_cut_off_from_the_goal_did_not_reach_it():
    """Three robots sealed in a room without a door, one in the goal's room (the euclidean field): the
    arrival rule ends the plan when the one that can arrives, and result.json said reached_goal true with
    1 of 4 robots there and the centroid 12 m off a 3 m goal radius."""
    from mrfswarm.config import from_dict
    from mrfswarm.pipeline import plan

    rows = ["......#.............."] * 4
    cfg = from_dict({"scenario": {"map": {"kind": "ascii", "rows": rows}, "robot_radius": 0.2, "goal": [19, 2],
                                  "start": {"positions": [[1, 1], [2, 1], [3, 1], [8, 1]]}},
                     "goal_potential": {"distance": "euclidean"}, "smoothing": {"enabled": False}})
    r = plan(cfg, progress=False)
    s = r.summary()
    assert r.discrete.stop_reason == "arrived" and s["robots_at_goal"] == 1
    assert s["reached_goal"] is False


# ---------------------------------------------------------------- voxels and downwash


def test_min_separation_is_in_the_downwash_scaled_metric_within_steps():
    # robot 0 slides under robot 1 (one voxel above the middle of its move)
    paths = np.array([[[0, 0, 0], [1, 0, 1]], [[2, 0, 0], [1, 0, 1]]])
    assert min_separation(paths) == pytest.approx(1.0)
    assert min_separation(paths, downwash=2.0) == pytest.approx(0.5)
    assert min_separation(paths[:1], downwash=2.0) == pytest.approx(np.hypot(1.0, 0.5))


@pytest.mark.parametrize("steps", [1, 2])
@pytest.mark.parametrize("z0", range(8))
def test_min_separation_of_robots_one_scaled_cell_apart_is_exactly_one(z0, steps):
    """Two robots stacked 3 voxels apart at downwash 3 are one cell apart in the scaled metric; scaling the positions
    before subtracting them gave 0.9999999999999999 (z0 = 2) or 0.9999999999999998 (z0 = 4), which result.json
    printed as it was (a 3-D tour)."""
    p = np.array([[[0, 0, z0], [0, 0, z0 + 3]], [[1, 0, z0], [1, 0, z0 + 3]]])[:steps]
    assert min_separation(p, downwash=3.0) == 1.0


def test_obstacle_clearance_in_3d_matches_brute_force():
    rng = np.random.default_rng(0)
    occupied = rng.random((8, 7, 6)) < 0.1
    pts = rng.uniform(-0.5, 5.5, (300, 3))  # on the map
    cells = np.argwhere(occupied).astype(float)
    g = np.maximum(np.abs(pts[:, None] - cells[None]) - 0.5, 0.0)
    edge = np.minimum(pts + 0.5, np.array(occupied.shape) - 0.5 - pts).min()
    assert obstacle_clearance(occupied, pts) == pytest.approx(min(np.linalg.norm(g, axis=-1).min(), edge))
    assert obstacle_clearance(occupied, pts[:1] - 2.0) == 0.0  # off the map


def test_path_clearance_and_lengths_in_3d():
    occupied = np.zeros((6, 6, 6), bool)
    occupied[3, 3, 3] = True
    paths = np.array([[[0, 0, 0], [5, 5, 0]], [[1, 1, 1], [5, 5, 1]], [[2, 2, 2], [5, 5, 3]]])
    m = discrete_metrics(paths, occupied, resolution=0.5, goal=np.array([3.0, 3.0, 2.0]), goal_radius=2.0,
                         downwash=2.0)
    assert np.allclose(m.path_lengths, [2 * np.sqrt(3) * 0.5, 3 * 0.5])
    # robot 0 passes (2, 2, 2), whose nearest point to the voxel (3, 3, 3) is sqrt(3) * 0.5 cells away
    s = np.linspace(0, 1, 2001)[:, None]
    pts = np.concatenate([paths[0, 0] + s * (paths[1, 0] - paths[0, 0]), paths[1, 0] + s * (paths[2, 0] - paths[1, 0])])
    brute = np.linalg.norm(np.maximum(np.abs(pts - 3.0) - 0.5, 0), axis=1).min()
    edge = np.minimum(paths + 0.5, 6 - 0.5 - paths).min()  # robot 0 starts in a corner of the map: half a cell
    assert m.min_obstacle_clearance == pytest.approx(min(brute, edge) * 0.5, abs=1e-3)
    inner = discrete_metrics(np.array([[[2, 2, 2]], [[2, 2, 2]]]), occupied, resolution=0.5)
    assert inner.min_obstacle_clearance == pytest.approx(np.sqrt(3) * 0.5 * 0.5)  # (2, 2, 2): the voxel's corner
    # robots 5 apart in x and y: the z scaling does not matter here
    assert m.min_separation == pytest.approx(min_separation(paths, 2.0) * 0.5)
    assert m.reached_goal is not None


def test_a_run_logs_its_stages_for_a_user_without_a_terminal(caplog):
    """-v on a long run without a progress bar printed four lines in 3 minutes (big-swarm tour): each stage
    says it starts, the smoothing every tenth of its windows, the outputs where they go."""
    from mrfswarm.config import load_config
    from mrfswarm.outputs import write_outputs
    from mrfswarm.pipeline import plan
    from support.repository import EXPERIMENTS

    with caplog.at_level("INFO"):
        r = plan(load_config(EXPERIMENTS / "free10.toml", ["simulation.enabled=false"]), progress=False)
    text = caplog.text
    assert "continuous stage: 10 robots, 7 steps in 2 windows" in text
    assert "smoothing: window 1 of 2" in text and "smoothing: window 2 of 2" in text
    caplog.clear()
    import tempfile
    from pathlib import Path

    with tempfile.TemporaryDirectory() as d, caplog.at_level("INFO"):
        write_outputs(r, Path(d) / "run")
    assert "writing the outputs to" in caplog.text
