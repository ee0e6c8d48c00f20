"""Units: the potentials' lengths count cells, everything placed in the world is metres.

The rule (``docs/contracts.md``, :mod:`mrfswarm.discrete.potentials`): ``interaction.k_a``,
``interaction.k_r``, ``goal_potential.k``, ``obstacle_potential.sigma``, ``mrf.order`` and
``smoothing.region_growth`` are in cells (the paper's table is at its 1 m cells), so the
same map drawn at a finer resolution, with its positions scaled, gets the same discrete
plan in cells. Unset ``scenario.goal_radius`` and ``scenario.start.sigma`` are 3 and 2
cells; given, they are metres.
"""

import re

import numpy as np
import pytest

from mrfswarm.cli import main
from mrfswarm.config import from_dict
from mrfswarm.errors import ConfigError
from mrfswarm.pipeline import plan
from mrfswarm.scenario import build_scenario

# a room with a wall and a gap (2 cells wide) between the swarm and its goal
ROOM = [
    "....................",
    "....................",
    ".........#..........",
    ".........#..........",
    ".........#..........",
    ".........#..........",
    "....................",
    "....................",
    ".........#..........",
    ".........#..........",
    ".........#..........",
    "....................",
]
STARTS = [[1, 3], [1, 5], [1, 7], [2, 4], [2, 6], [3, 5]]  # cells = metres at 1 m
GOAL = [17, 6]


def room(res: float, *, sampled: bool = False, **sections) -> dict:
    """The room at ``res`` m cells, every position scaled so the cells stay the same."""
    start = ({"center": [2 * res, 5 * res], "n_robots": 6, "seed": 3} if sampled
             else {"positions": [[x * res, y * res] for x, y in STARTS]})
    data = {
        "scenario": {"map": {"kind": "ascii", "rows": ROOM, "resolution": res}, "start": start,
                     "goal": [GOAL[0] * res, GOAL[1] * res], "robot_radius": 0.2 * res},
        "interaction": {"k": 3},
        "smoothing": {"enabled": False},
        "simulation": {"enabled": False},
    }
    for name, table in sections.items():
        data.setdefault(name, {}).update(table)
    return data


@pytest.mark.parametrize("res", [0.5, 0.25])
@pytest.mark.parametrize("variant", [
    {},
    {"sampled": True},  # the default sigma counts cells: the same start cells
    {"goal_potential": {"distance": "euclidean"}, "mrf": {"contested": "nearest", "progress": "energy"}},
    {"interaction": {"k_a": 10.0, "k_r": 3.0}, "goal_potential": {"k": 12.0}, "obstacle_potential": {"sigma": 1.5}},
], ids=["default", "sampled-start", "paper-rules", "other-lengths"])
def test_the_plan_in_cells_does_not_depend_on_the_resolution(res, variant):
    variant = dict(variant)
    sampled = variant.pop("sampled", False)
    coarse = plan(from_dict(room(1.0, sampled=sampled, **variant)))
    fine = plan(from_dict(room(res, sampled=sampled, **variant)))
    assert coarse.discrete.n_steps > 5
    assert np.array_equal(fine.scenario.start, coarse.scenario.start)
    np.testing.assert_array_equal(fine.scenario.static, coarse.scenario.static)  # bit for bit (res a power of 2)
    np.testing.assert_array_equal(fine.discrete.paths, coarse.discrete.paths)
    assert fine.discrete.stop_reason == coarse.discrete.stop_reason
    assert fine.scenario.morse.d_min == pytest.approx(coarse.scenario.morse.d_min * res, rel=1e-12)
    a, b = coarse.summary(), fine.summary()
    assert b["robots_at_goal"] == a["robots_at_goal"]
    assert [r["stop_reason"] for r in b["robots"]] == [r["stop_reason"] for r in a["robots"]]
    assert b["goal_region_radius_m"] == pytest.approx(a["goal_region_radius_m"] * res, rel=1e-12)
    assert b["separation_threshold_m"] == pytest.approx(a["separation_threshold_m"] * res, rel=1e-12)
    # and the outputs are in metres: the discrete paths scale
    np.testing.assert_allclose(fine.discrete_paths_world(), coarse.discrete_paths_world() * res)


def test_goal_radius_counts_cells_when_unset_and_metres_when_given():
    assert build_scenario(from_dict(room(0.25))).goal_radius == pytest.approx(0.75)
    assert build_scenario(from_dict(room(1.0))).goal_radius == pytest.approx(3.0)  # the paper's 3 m
    given = room(0.25)
    given["scenario"]["goal_radius"] = 1.0
    scn = build_scenario(from_dict(given))
    assert scn.goal_radius == 1.0
    assert scn.goal_region_radius == pytest.approx(build_scenario(from_dict(room(0.25))).goal_region_radius + 0.25)


def test_the_start_spread_counts_cells_when_unset_and_metres_when_given():
    sampled = room(0.25, sampled=True)
    unset = build_scenario(from_dict(sampled)).start
    sampled["scenario"]["start"]["sigma"] = 0.5  # 2 cells of 0.25 m, given in metres: the same draws
    assert np.array_equal(build_scenario(from_dict(sampled)).start, unset)
    sampled["scenario"]["start"]["sigma"] = 2.0  # 2 m: 8 cells, a different swarm
    assert not np.array_equal(build_scenario(from_dict(sampled)).start, unset)


def test_goal_radius_must_be_positive():
    bad = room(0.25)
    bad["scenario"]["goal_radius"] = 0.0
    with pytest.raises(ConfigError, match=r"^scenario\.goal_radius = 0\.0: must be > 0 \(metres\)$"):
        from_dict(bad)


def test_the_default_robot_radius_on_quarter_metre_cells_is_a_one_line_error(tmp_path, capsys):
    """robot_radius (metres, default 0.25) must be below half a cell: 0.125 m on 0.25 m cells."""
    cfg = tmp_path / "c.toml"
    cfg.write_text('[scenario]\nmap = { kind = "free", size = [24, 16], resolution = 0.25 }\n'
                   "start = { positions = [[0.5, 0.5], [0.5, 1.0], [1.0, 0.5]] }\ngoal = [5, 3]\n"
                   "[interaction]\nk = 2\n[simulation]\nenabled = false\n")
    rc = main(["run", str(cfg), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1
    assert re.search(r"scenario\.robot_radius = 0\.25 m must be below half a cell \(0\.125 m on this map; "
                     r"scenario\.map\.coarsen = 3 draws it in 0\.75 m cells\)", err[0])
    assert not (tmp_path / "o" / "result.json").exists()
    # a radius below half a cell is accepted (the discrete stage alone is enough to show it)
    rc = main(["run", str(cfg), "--out", str(tmp_path / "ok"), "--set", "scenario.robot_radius=0.1",
               "--set", "smoothing.enabled=false"])
    assert rc == 0
