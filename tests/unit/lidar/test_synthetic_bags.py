"""The synthetic LiDAR generator: deterministic, readable by rosbags and by KISS-ICP's own loader."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from coral.lidar import clouds, generating, trajectory
from coral.lidar.generating import BagParams


def _first_cloud(bag: Path) -> tuple[object, int]:
    from rosbags.highlevel import AnyReader

    with AnyReader([bag]) as reader:
        connection = next(c for c in reader.connections if c.topic == generating.POINTS_TOPIC)
        _, stamp, raw = next(reader.messages(connections=[connection]))
        return reader.deserialize(raw, connection.msgtype), stamp


def test_a_bag_holds_one_cloud_and_one_ground_truth_pose_per_scan(short_dataset: Path) -> None:
    from rosbags.highlevel import AnyReader

    with AnyReader([short_dataset / "bag"]) as reader:
        counts = {name: info.msgcount for name, info in reader.topics.items()}
        types = {name: info.msgtype for name, info in reader.topics.items()}
    assert counts == {generating.POINTS_TOPIC: 40, generating.GROUND_TRUTH_TOPIC: 40}
    assert types[generating.POINTS_TOPIC] == "sensor_msgs/msg/PointCloud2"
    assert types[generating.GROUND_TRUTH_TOPIC] == "nav_msgs/msg/Odometry"
    stamps, poses = trajectory.read_poses_csv(short_dataset / "ground_truth.csv")
    assert len(stamps) == 40 and np.allclose(poses[0], np.eye(4), atol=1e-6)
    assert np.all(np.diff(stamps) == 100_000_000)  # 10 Hz
    assert json.loads((short_dataset / "params.json").read_text())["seed"] == 11


def test_scans_have_finite_points_from_several_beams_and_spread_point_times(short_dataset: Path) -> None:
    message, _ = _first_cloud(short_dataset / "bag")
    points, times = clouds.decode(
        message.fields, message.data, message.point_step, message.width, message.height
    )
    assert [f.name for f in message.fields] == ["x", "y", "z", "t"]
    assert len(points) > 5000 and np.isfinite(points).all()
    assert times is not None and 0.0 <= times.min() and times.max() < 0.1 and np.ptp(times) > 0.09
    elevations = np.degrees(np.arctan2(points[:, 2], np.linalg.norm(points[:, :2], axis=1)))
    assert len(np.unique(np.round(elevations))) >= 10  # many beams, not one plane
    ranges = np.linalg.norm(points, axis=1)
    assert ranges.min() > 0.3 and ranges.max() <= 40.5


def test_the_same_seed_gives_the_same_scans_and_another_seed_does_not(tmp_path: Path) -> None:
    small = BagParams(seed=3, scans=2, columns=128, beams=4)
    first = generating.generate(small, tmp_path / "a")
    again = generating.generate(small, tmp_path / "b")
    other = generating.generate(BagParams(seed=4, scans=2, columns=128, beams=4), tmp_path / "c")
    data = [bytes(_first_cloud(d / "bag")[0].data) for d in (first, again, other)]
    assert data[0] == data[1]
    assert data[0] != data[2]
    assert small.key() != BagParams(seed=4, scans=2, columns=128, beams=4).key()


def test_the_cache_generates_a_dataset_once(tmp_path: Path) -> None:
    small = BagParams(seed=5, scans=2, columns=128, beams=4)
    folder = generating.cached_dataset(small, tmp_path)
    written = (folder / "params.json").stat().st_mtime_ns
    assert generating.cached_dataset(small, tmp_path) == folder
    assert (folder / "params.json").stat().st_mtime_ns == written
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".staging")]


def test_asking_for_more_scans_than_the_path_lasts_is_refused_with_the_reason(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="need .* s of path"):
        generating.generate(BagParams(seed=1, scans=5000, columns=64, beams=2), tmp_path / "x")
    assert not (tmp_path / "x").exists()


@pytest.mark.parametrize(
    ("fields", "message"),
    [
        ({"speed": float("nan")}, "speed must be a number of m/s of at least 0, not nan"),
        ({"speed": -1.0}, "speed must be a number of m/s of at least 0, not -1.0"),
        ({"beams": 100_000}, "a scan of 100000 beams by 1024 columns is not a LiDAR's"),
        ({"columns": 8}, "a scan of 16 beams by 8 columns is not a LiDAR's"),
    ],
)
def test_a_sensor_no_lidar_has_is_refused_before_any_work(fields: dict[str, float], message: str) -> None:
    with pytest.raises(ValueError, match=message):
        BagParams(**fields)  # type: ignore[arg-type]


def test_generate_bag_names_a_speed_that_is_not_a_number(tmp_path: Path) -> None:
    from click.testing import CliRunner
    from coral_core.command import main

    result = CliRunner().invoke(main, ["generate-bag", "--speed", "nan", "--output", str(tmp_path / "bag")])
    assert result.exit_code == 2 and "speed must be a number of m/s of at least 0, not nan" in result.output
    assert not (tmp_path / "bag").exists()


def test_kiss_icps_own_rosbag_loader_reads_the_bag(short_dataset: Path) -> None:
    from kiss_icp.datasets.rosbag import RosbagDataset

    dataset = RosbagDataset(short_dataset / "bag", topic=generating.POINTS_TOPIC)
    points, times = dataset[0]
    assert len(dataset) == 40
    assert points.shape[1] == 3 and len(points) == len(times) > 5000
