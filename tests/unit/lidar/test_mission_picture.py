"""The SLAM report draws the map, the estimated and the true trajectory into a PNG beside the map."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from coral.lidar import demo, mapfile, picture, trajectory
from fixtures.pictures import GREEN, RED, count_near, pixels


def _mission_output(dataset: Path, folder: Path, offset_m: float) -> Path:
    """A map and a trajectory as the SLAM skillset saves them: the truth shifted by `offset_m` in y."""
    folder.mkdir()
    stamps, truth = trajectory.read_poses_csv(dataset / "ground_truth.csv")
    estimate = truth.copy()
    estimate[:, 1, 3] += offset_m * np.linspace(0.0, 1.0, len(estimate))
    trajectory.write_poses_csv(folder / "slam_map.trajectory.csv", stamps, estimate)
    rng = np.random.default_rng(3)
    walls = truth[:, :3, 3].repeat(50, axis=0) + rng.normal(0.0, 2.0, (len(truth) * 50, 3))
    mapfile.write_ply(folder / demo.EXAMPLE_MAP_NAME, walls)
    return folder


def test_the_report_scores_the_run_and_draws_it_beside_the_map(short_dataset: Path, tmp_path: Path) -> None:
    output = _mission_output(short_dataset, tmp_path / "out", offset_m=0.5)
    evaluation = demo.evaluate(output, short_dataset)

    assert evaluation.scans == evaluation.ground_truth_scans == 40
    assert evaluation.map_points == 40 * 50
    assert evaluation.error is not None and 0.001 < evaluation.error.ate_rmse_m < 0.5
    assert evaluation.picture_path == output / "slam_map.png"
    rgb = pixels(evaluation.picture_path, picture.SIZE_PX)
    assert count_near(rgb, RED) > 200 and count_near(rgb, GREEN) > 200
    summary = "\n".join(evaluation.summary())
    assert f"Picture           : {output / 'slam_map.png'}" in summary
    assert f"ATE {evaluation.error.ate_rmse_m:.3f} m RMSE" in summary


def test_no_picture_is_drawn_when_the_mission_saved_nothing(short_dataset: Path, tmp_path: Path) -> None:
    evaluation = demo.evaluate(tmp_path, short_dataset)
    assert evaluation.scans == 0 and evaluation.error is None and evaluation.picture_path is None
    assert not list(tmp_path.glob("*.png"))
    assert "Trajectory error  : not available" in "\n".join(evaluation.summary())


def test_a_run_of_one_scan_is_drawn_without_an_error_figure(short_dataset: Path, tmp_path: Path) -> None:
    output = _mission_output(short_dataset, tmp_path / "out", offset_m=0.0)
    stamps, poses = trajectory.read_poses_csv(output / "slam_map.trajectory.csv")
    trajectory.write_poses_csv(output / "slam_map.trajectory.csv", stamps[:1], poses[:1])
    evaluation = demo.evaluate(output, short_dataset)
    assert evaluation.error is None and evaluation.picture_path is not None
    pixels(evaluation.picture_path, picture.SIZE_PX)
