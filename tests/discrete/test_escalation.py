"""A step the plan's MRF method leaves without progress short of the goal is solved again jointly
(``mrf.escalation``): ICM moves one robot at a time, and two robots that each wait for the cell the other
blocks stay there; a joint solution of the same step MRF steps one aside."""

from __future__ import annotations

import numpy as np
import pytest

from mrfswarm.config import from_dict
from mrfswarm.pipeline import plan


def room(tmp_path):
    """The new-user tour's room: 0.5 m voxels, a wall at x = 6 with a one-voxel window (y 5, z 3) and a
    one-voxel gap (y 2, z 1), a small block beyond; 4 robots, downwash 1.5. ICM alone left robots 1 and 3
    in the column below and above the window's near side, each waiting for the voxel in front of it, which
    the other's downwash keeps."""
    occ = np.zeros((12, 8, 5), dtype=bool)
    occ[6] = True
    occ[6, 2, 1] = occ[6, 5, 3] = False
    occ[9:11, 1:3, 0:3] = True
    np.save(tmp_path / "room.npy", occ)
    return {"scenario": {"map": {"kind": "npy", "path": "room.npy", "resolution": 0.5, "origin": [0.25, 0.25, 0.25]},
                         "start": {"positions": [[0.75, 1.25, 0.75], [0.75, 2.25, 0.75], [1.25, 1.75, 1.25],
                                                 [0.75, 3.25, 1.75]]},
                         "goal": [5.75, 3.75, 1.25], "robot_radius": 0.2, "downwash": 1.5},
            "smoothing": {"enabled": False}, "simulation": {"enabled": False}}


def test_a_step_icm_leaves_stuck_is_solved_jointly_and_the_swarm_arrives(tmp_path):
    r = plan(from_dict(room(tmp_path), tmp_path), progress=False)
    s = r.summary()
    assert s["robots_at_goal"] == 4 and r.discrete.stop_reason == "arrived"
    assert r.discrete.escalated >= 1 and s["escalated"] == r.discrete.escalated


def test_without_escalation_the_plan_stops_there_as_the_papers(tmp_path):
    data = room(tmp_path)
    data["mrf"] = {"escalation": "none"}
    r = plan(from_dict(data, tmp_path), progress=False)
    assert r.summary()["robots_at_goal"] == 2 and r.discrete.stop_reason == "trapped"
    assert r.discrete.escalated == 0


def test_the_escalation_is_a_method_name_or_none(tmp_path):
    from mrfswarm.errors import ConfigError

    with pytest.raises(ConfigError, match=r"^mrf\.escalation = 'jointly': must be one of none, icm"):
        from_dict({"mrf": {"escalation": "jointly"}})
