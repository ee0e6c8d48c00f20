"""The uav_trajectories / Crazyswarm CSV: header, padding, round trip, refusal to truncate."""

import numpy as np
import pytest

from mrfswarm.errors import ScenarioError
from mrfswarm.trajectory import PiecewisePolynomial, read_uav_csv, solve_min_snap, write_uav_csv
from mrfswarm.trajectory.uav_csv import HEADER, format_csv
from solvers.errors import InvalidProblem
from support.trajectories import random_walk


def test_header_is_the_uav_trajectories_one():
    assert HEADER[0] == "duration" and HEADER[1] == "x^0" and HEADER[8] == "x^7"
    assert HEADER[9] == "y^0" and HEADER[17] == "z^0" and HEADER[25] == "yaw^0" and HEADER[-1] == "yaw^7"
    assert len(HEADER) == 33


def test_round_trip_3d_is_exact(tmp_path):
    rng = np.random.default_rng(0)
    W = random_walk(rng, 6, 3)
    traj = solve_min_snap(W, rng.uniform(0.5, 2.0, 6)).trajectory
    path = tmp_path / "t.csv"
    write_uav_csv(traj, path)
    back = read_uav_csv(path)
    np.testing.assert_array_equal(back.durations, traj.durations)
    np.testing.assert_array_equal(back.coefficients, traj.coefficients)


def test_2d_gets_altitude_and_zero_yaw(tmp_path):
    rng = np.random.default_rng(1)
    W = random_walk(rng, 4)
    traj = solve_min_snap(W, np.ones(4)).trajectory
    path = tmp_path / "t.csv"
    write_uav_csv(traj, path, altitude=1.25)
    back = read_uav_csv(path, dim=4)
    t = np.linspace(0, traj.duration, 100)
    np.testing.assert_array_equal(back(t)[:, :2], traj(t))
    np.testing.assert_allclose(back(t)[:, 2], 1.25)
    np.testing.assert_allclose(back(t)[:, 3], 0.0)
    np.testing.assert_array_equal(read_uav_csv(path, dim=2).coefficients, traj.coefficients)


def test_lower_degree_is_zero_padded(tmp_path):
    traj = solve_min_snap([[0.0, 0.0], [1.0, 2.0], [3.0, 2.0]], [1.0, 1.5], degree=5, derivative=3).trajectory
    path = tmp_path / "t.csv"
    write_uav_csv(traj, path)
    back = read_uav_csv(path, dim=2)
    assert back.degree == 7
    np.testing.assert_array_equal(back.coefficients[:, 6:], 0.0)
    np.testing.assert_array_equal(back.with_degree(5).coefficients, traj.coefficients)


def test_degree_above_7_cannot_be_exported(tmp_path):
    traj = PiecewisePolynomial([1.0], np.ones((1, 10, 2)))
    path = tmp_path / "t.csv"
    with pytest.raises(InvalidProblem, match="degree-9 .* cannot be exported"):
        write_uav_csv(traj, path)
    assert not path.exists() and list(tmp_path.iterdir()) == []


def test_text_is_one_row_per_piece():
    traj = PiecewisePolynomial([0.5, 2.0], np.zeros((2, 8, 3)))
    lines = format_csv(traj).splitlines()
    assert lines[0] == ",".join(HEADER) and len(lines) == 3
    assert lines[1].split(",")[0] == "0.5" and len(lines[1].split(",")) == 33


@pytest.mark.parametrize("text,match", [
    ("", "empty"),
    ("duration,x^0\n1,2\n", "header"),
    (",".join(HEADER) + "\n1," + ",".join(["0"] * 31) + "\n", "expected 33"),
    (",".join(HEADER) + "\n0," + ",".join(["0"] * 32) + "\n", "duration must be positive"),
    (",".join(HEADER) + "\n1,abc," + ",".join(["0"] * 31) + "\n", "not a number"),
    (",".join(HEADER) + "\n1,nan," + ",".join(["0"] * 31) + "\n", "finite"),
])
def test_read_errors(tmp_path, text, match):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(ScenarioError, match=match):
        read_uav_csv(path)


def test_a_file_that_is_not_text_is_one_error_naming_it(tmp_path):
    p = tmp_path / "binary.csv"
    p.write_bytes(b"\xff\xfe\x00duration,x^0\n")
    with pytest.raises(ScenarioError, match=r"binary\.csv: not a text file$"):
        read_uav_csv(p)
