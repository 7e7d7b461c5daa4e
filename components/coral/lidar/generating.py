"""Writes a synthetic LiDAR ROS 2 bag with ground truth, deterministically from a seed, and caches it.

Layout of one dataset folder (what `generate` returns):

    <dataset>/bag/                 rosbag2 (sqlite3): /lidar/points (sensor_msgs/PointCloud2, fields
                                   x, y, z, t: float32, t = seconds since the sweep started) and
                                   /ground_truth (nav_msgs/Odometry, same stamp as the scan)
    <dataset>/ground_truth.csv     stamp_ns, x, y, z, qx, qy, qz, qw per scan
    <dataset>/params.json          the parameters (the cache key is their hash)

Ground-truth poses are the sensor's pose at the middle of each sweep, relative to the first one:
the frame KISS-ICP deskews into, so estimates and truth compare without a time offset.
Called by the `coral generate-bag` verb, the demo, the tests and the SLAM benchmark.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import os
import shutil
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from coral.lidar import clouds, trajectory
from coral.lidar.motion import Motion, quaternion_from_matrix
from coral.lidar.scene import build_scene
from coral.lidar.sensor import SensorModel, sweep

POINTS_TOPIC = "/lidar/points"
GROUND_TRUTH_TOPIC = "/ground_truth"
START_NS = 1_700_000_000_000_000_000
FORMAT_VERSION = 1


# The largest spinning LiDARs: 128 lasers, 4096 columns a sweep.
MAX_BEAMS = 128
MAX_COLUMNS = 4096


@dataclass(frozen=True)
class BagParams:
    """Everything that determines the bag's content; equal params give byte-equal scans."""

    seed: int = 7
    scans: int = 300
    beams: int = 16
    columns: int = 1024
    speed: float = 1.0
    range_noise: float = 0.01
    rooms: int = 4

    def __post_init__(self) -> None:
        # NaN would fill the bag with NaN points; a sensor beyond the largest spinning LiDARs would
        # need gigabytes a scan before anything said so.
        if not (math.isfinite(self.speed) and self.speed >= 0):
            raise ValueError(f"speed must be a number of m/s of at least 0, not {self.speed}")
        if not (2 <= self.beams <= MAX_BEAMS and 16 <= self.columns <= MAX_COLUMNS):
            raise ValueError(
                f"a scan of {self.beams} beams by {self.columns} columns is not a LiDAR's: "
                f"use 2 to {MAX_BEAMS} beams and 16 to {MAX_COLUMNS} columns"
            )

    def key(self) -> str:
        text = json.dumps({**dataclasses.asdict(self), "format": FORMAT_VERSION}, sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:16]


def default_cache_root() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "coral-on-kubernetes" / "bags"


Progress = Callable[[int, int], None]
"""Told `(scans written, scans in all)` after each scan."""


def cached_dataset(
    params: BagParams, cache_root: Path | None = None, progress: Progress | None = None
) -> Path:
    """Folder of the dataset for `params`, generating it first if the cache lacks it."""
    root = cache_root or default_cache_root()
    target = root / f"seed{params.seed}-n{params.scans}-{params.key()}"
    if (target / "params.json").is_file():
        return target
    return generate(params, target, progress)


def generate(params: BagParams, target: Path, progress: Progress | None = None) -> Path:
    """Generates the dataset into `target` atomically (built aside, then renamed into place)."""
    target.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=".staging-", dir=target.parent))
    try:
        _write_dataset(params, staging, progress or (lambda done, total: None))
        try:
            staging.rename(target)
        except OSError:
            # Another process finished the same dataset first: theirs is identical, keep it.
            if not (target / "params.json").is_file():
                raise
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return target


def _write_dataset(params: BagParams, folder: Path, progress: Progress) -> None:
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    scene = build_scene(params.seed, rooms=params.rooms)
    motion = Motion(path=scene.path, speed=params.speed)
    sensor = SensorModel(beams=params.beams, columns=params.columns, range_noise=params.range_noise)
    rng = np.random.default_rng(params.seed + 1)
    starts = np.arange(params.scans) * sensor.period
    if starts[-1] + sensor.period > motion.duration:
        raise ValueError(
            f"{params.scans} scans at {params.speed} m/s need {starts[-1] + sensor.period:.1f} s of path; "
            f"the scene's path lasts {motion.duration:.1f} s (use fewer scans, lower speed or more rooms)"
        )
    mid_poses = motion.poses(starts + sensor.period / 2)
    relative = np.linalg.inv(mid_poses[0]) @ mid_poses

    stamps: list[int] = []
    with Writer(folder / "bag", version=9) as writer:
        points_conn = writer.add_connection(POINTS_TOPIC, "sensor_msgs/msg/PointCloud2", typestore=store)
        truth_conn = writer.add_connection(GROUND_TRUTH_TOPIC, "nav_msgs/msg/Odometry", typestore=store)
        for index, start in enumerate(starts):
            stamp_ns = START_NS + int(round(start * 1e9))
            scan = sweep(scene, motion, sensor, float(start), rng)
            header = clouds.header(store, stamp_ns, "lidar")
            cloud = clouds.xyzt_cloud(store, header, scan.points, scan.times)
            writer.write(points_conn, stamp_ns, store.serialize_cdr(cloud, cloud.__msgtype__))
            odometry = _odometry(store, header, relative[index])
            writer.write(truth_conn, stamp_ns, store.serialize_cdr(odometry, odometry.__msgtype__))
            stamps.append(stamp_ns)
            progress(index + 1, len(starts))
    trajectory.write_poses_csv(folder / "ground_truth.csv", np.asarray(stamps, dtype=np.int64), relative)
    (folder / "params.json").write_text(json.dumps(dataclasses.asdict(params), indent=2) + "\n")


def _odometry(store: object, header: object, pose: np.ndarray) -> object:
    types = store.types  # type: ignore[attr-defined]
    qx, qy, qz, qw = quaternion_from_matrix(pose[:3, :3])
    vector = types["geometry_msgs/msg/Vector3"]
    return types["nav_msgs/msg/Odometry"](
        header=header,
        child_frame_id="lidar",
        pose=types["geometry_msgs/msg/PoseWithCovariance"](
            pose=types["geometry_msgs/msg/Pose"](
                position=types["geometry_msgs/msg/Point"](x=pose[0, 3], y=pose[1, 3], z=pose[2, 3]),
                orientation=types["geometry_msgs/msg/Quaternion"](x=qx, y=qy, z=qz, w=qw),
            ),
            covariance=np.zeros(36),
        ),
        twist=types["geometry_msgs/msg/TwistWithCovariance"](
            twist=types["geometry_msgs/msg/Twist"](
                linear=vector(x=0.0, y=0.0, z=0.0), angular=vector(x=0.0, y=0.0, z=0.0)
            ),
            covariance=np.zeros(36),
        ),
    )
