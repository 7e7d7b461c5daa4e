"""Trajectory error (ATE after rigid alignment, RPE) and the pose CSV format."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from coral.lidar import trajectory
from coral.lidar.motion import rotation_zyx


def _path(n: int = 50) -> np.ndarray:
    poses = np.repeat(np.eye(4)[None], n, axis=0)
    t = np.linspace(0, 5, n)
    poses[:, 0, 3], poses[:, 1, 3] = t, np.sin(t)
    poses[:, :3, :3] = rotation_zyx(np.cos(t), np.zeros(n), np.zeros(n))
    return poses


def test_identical_trajectories_have_no_error() -> None:
    error = trajectory.trajectory_error(_path(), _path())
    assert error.ate_rmse_m == pytest.approx(0.0, abs=1e-9)
    assert error.rpe_rmse_m == pytest.approx(0.0, abs=1e-9)


def test_an_estimate_in_another_frame_is_aligned_before_scoring() -> None:
    offset = np.eye(4)
    offset[:3, :3] = rotation_zyx(np.array([1.0]), np.array([0.1]), np.array([0.0]))[0]
    offset[:3, 3] = [3.0, -2.0, 0.5]
    error = trajectory.trajectory_error(offset @ _path(), _path())
    assert error.ate_rmse_m == pytest.approx(0.0, abs=1e-6)


def test_a_constant_position_error_shows_as_ate_and_rpe() -> None:
    truth = _path()
    estimate = truth.copy()
    estimate[::2, 2, 3] += 0.2  # every other pose 20 cm too high: alignment cannot remove it
    error = trajectory.trajectory_error(estimate, truth)
    assert 0.05 < error.ate_rmse_m < 0.2
    assert error.rpe_rmse_m == pytest.approx(0.2, rel=0.05)


def test_poses_survive_a_csv_round_trip(tmp_path: Path) -> None:
    stamps = np.arange(50, dtype=np.int64) * 100
    trajectory.write_poses_csv(tmp_path / "t.csv", stamps, _path())
    read_stamps, read_poses = trajectory.read_poses_csv(tmp_path / "t.csv")
    assert list(read_stamps) == list(stamps)
    assert np.allclose(read_poses, _path(), atol=1e-6)


def test_a_malformed_csv_row_is_named_by_file_and_line(tmp_path: Path) -> None:
    path = tmp_path / "bad.csv"
    path.write_text("stamp_ns,x,y,z,qx,qy,qz,qw\n1,0,0,0,0,0,0,1\n2,0,0,0\n")
    with pytest.raises(ValueError, match=rf"{path}:3: expected 8 columns"):
        trajectory.read_poses_csv(path)


def test_matching_by_stamp_drops_poses_missing_on_either_side() -> None:
    est, truth = trajectory.match_by_stamp(np.array([1, 2, 4]), _path(3), np.array([1, 2, 3, 4]), _path(4))
    assert len(est) == len(truth) == 3
    assert np.allclose(est[2], _path(3)[2]) and np.allclose(truth[2], _path(4)[3])
