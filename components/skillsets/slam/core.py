"""The SLAM skillset's engine: KISS-ICP odometry with input sanitising, a global map and map files.

Pure Python around `kiss_icp.kiss_icp.KissICP`, with no ROS: the skillset node
(`coral_skillsets.slam.skillset`) feeds it decoded scans, and the benchmark and tests use it
directly. KISS-ICP aborts the whole process through a C++ assertion when a scan holds NaN points or
when deskewing runs on points whose timestamps are all equal, so every scan is sanitised first:
non-finite points are dropped, unusable per-point times disable deskewing for that scan only, and a
scan with too few points left is rejected with `ScanRejected` (one failed behavior, not a crash).
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from coral.lidar import trajectory
from coral.lidar.mapfile import MapFileError, read_ply, write_ply


class ScanRejected(ValueError):
    """The scan cannot be registered; the message says why (the pose is left unchanged)."""


@dataclass(frozen=True)
class SlamConfig:
    max_range: float = 40.0
    min_range: float = 0.3
    deskew: bool = True
    voxel_size: float | None = None  # default: max_range / 100, as KISS-ICP does
    max_points_per_voxel: int = 20
    min_points: int = 100
    map_voxel_size: float = 0.2  # resolution of the saved global map
    map_keyframe_m: float = 0.5  # a scan joins the global map after this much motion (or 10 degrees)
    max_threads: int = 0

    @property
    def kiss_voxel_size(self) -> float:
        return self.voxel_size or self.max_range / 100.0

    def kiss_config(self) -> object:
        from kiss_icp.config import KISSConfig

        config = KISSConfig()
        config.data.max_range = self.max_range
        config.data.min_range = self.min_range
        config.data.deskew = self.deskew
        config.mapping.voxel_size = self.kiss_voxel_size
        config.mapping.max_points_per_voxel = self.max_points_per_voxel
        config.registration.max_num_threads = self.max_threads
        return config


@dataclass(frozen=True)
class Sanitised:
    points: np.ndarray  # (N, 3) float64, all finite
    times: np.ndarray  # (N,) float64, or empty when deskewing must be skipped
    dropped: int
    deskew: bool


def sanitise(points: np.ndarray, times: np.ndarray | None, deskew: bool = True) -> Sanitised:
    """Makes a scan safe for KISS-ICP's native code (pure function).

    Raises:
        ScanRejected: the array has the wrong shape.
    """
    points = np.asarray(points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 3:
        raise ScanRejected(f"points must be an (N, 3) array, got shape {points.shape}")
    finite = np.isfinite(points)
    # Column by column: numpy's `.all(axis=1)` over three columns takes about 8 times as long, on
    # the registration thread, for every scan.
    keep = finite[:, 0] & finite[:, 1] & finite[:, 2]
    usable_times = times is not None and deskew and len(times) == len(points)
    if usable_times:
        times = np.asarray(times, dtype=np.float64)
        keep &= np.isfinite(times)
    everything = bool(keep.all())  # the common case: no copies
    clean = points if everything else points[keep]
    clean_times = (times if everything else times[keep]) if usable_times else np.empty(0)  # type: ignore[index]
    # Deskewing divides by the spread of the timestamps: equal stamps would feed NaN into SO3::exp.
    if len(clean_times) == 0 or not float(np.ptp(clean_times)) > 0.0:
        clean_times = np.empty(0)
    return Sanitised(
        points=np.ascontiguousarray(clean),
        times=np.ascontiguousarray(clean_times),
        dropped=int(len(points) - len(clean)),
        deskew=len(clean_times) > 0,
    )


@dataclass
class ScanResult:
    index: int
    pose: np.ndarray
    points_used: int
    dropped: int
    deskewed: bool


@dataclass
class SlamCore:
    """Odometry and mapping state of one SLAM session; thread-safe.

    Two locks: `_odometry_lock` serialises KISS-ICP (one registration at a time) and `_state_lock`
    guards the trajectory, the map chunks and the displacement mark. Readers of the pose or the
    displacement take only the state lock, so a behavior asking where the robot is never waits for
    a registration in progress (KISS-ICP takes 20-30 ms per scan and holds the GIL meanwhile).
    """

    config: SlamConfig = field(default_factory=SlamConfig)

    def __post_init__(self) -> None:
        self._odometry_lock = threading.Lock()
        self._state_lock = threading.Lock()
        self.reset()

    def reset(self) -> None:
        with self._odometry_lock, self._state_lock:
            self._odometry = _odometry(self.config.kiss_config())
            self._stamps: list[int] = []
            self._poses: list[np.ndarray] = []
            self._map_chunks: list[np.ndarray] = []
            self._keyframe: np.ndarray | None = None
            self._prior_map = np.empty((0, 3))
            self._mark = np.eye(4)
            self.rejected = 0

    @property
    def scans_processed(self) -> int:
        return len(self._poses)

    @property
    def pose(self) -> np.ndarray:
        with self._state_lock:
            return self._last_pose()

    def _last_pose(self) -> np.ndarray:
        return self._poses[-1].copy() if self._poses else np.eye(4)

    def process(self, points: np.ndarray, times: np.ndarray | None, stamp_ns: int) -> ScanResult:
        """Registers one scan; raises `ScanRejected` (state unchanged) when it is unusable."""
        clean = sanitise(points, times, deskew=self.config.deskew)
        if len(clean.points) < self.config.min_points:
            with self._state_lock:
                self.rejected += 1
            raise ScanRejected(
                f"scan has {len(clean.points)} usable points after dropping {clean.dropped} non-finite ones "
                f"(need at least {self.config.min_points})"
            )
        with self._odometry_lock:
            frame, _ = self._odometry.register_frame(clean.points, clean.times)
            # Taken under the lock: the next registration replaces it.
            kiss_thinned = self._odometry.map_points
            pose = np.array(self._odometry.last_pose)
            if not np.isfinite(pose).all():
                raise ScanRejected("registration produced a non-finite pose")
            # Recorded while registrations are still serialised, so the trajectory keeps their order.
            with self._state_lock:
                self._poses.append(pose)
                self._stamps.append(int(stamp_ns))
                index = len(self._poses) - 1
                keyframe = self._is_keyframe(pose)
                if keyframe:
                    self._keyframe = pose
        if keyframe:
            # Keyframes only: consecutive scans overlap almost entirely, and thinning every one
            # would cost registration time for no new map content.
            thinned = self._thinned_for_map(frame, kiss_thinned)
            chunk = thinned @ pose[:3, :3].T + pose[:3, 3]
            with self._state_lock:
                self._map_chunks.append(chunk)
        return ScanResult(index, pose, len(clean.points), clean.dropped, clean.deskew)

    def _thinned_for_map(self, frame: np.ndarray, kiss_thinned: np.ndarray) -> np.ndarray:
        """The scan at the map's resolution; at the default resolution, half KISS-ICP's voxel,
        KISS-ICP has just thinned it so for its own local map (`kiss_thinned`), and that is reused."""
        if math.isclose(self.config.map_voxel_size, self.config.kiss_voxel_size * 0.5):
            return kiss_thinned
        from kiss_icp.voxelization import voxel_down_sample

        return np.asarray(voxel_down_sample(np.asarray(frame), self.config.map_voxel_size))

    def _is_keyframe(self, pose: np.ndarray) -> bool:
        if self._keyframe is None:
            return True
        delta = np.linalg.inv(self._keyframe) @ pose
        angle = math.acos(max(-1.0, min(1.0, (np.trace(delta[:3, :3]) - 1.0) / 2.0)))
        return bool(np.linalg.norm(delta[:3, 3]) >= self.config.map_keyframe_m or angle >= math.radians(10.0))

    def displacement(self) -> tuple[float, float]:
        """(metres, radians) moved since the last `mark_displacement` (or the start)."""
        with self._state_lock:
            delta = np.linalg.inv(self._mark) @ self._last_pose()
        angle = math.acos(max(-1.0, min(1.0, (np.trace(delta[:3, :3]) - 1.0) / 2.0)))
        return float(np.linalg.norm(delta[:3, 3])), angle

    def mark_displacement(self) -> None:
        with self._state_lock:
            self._mark = self._last_pose()

    def local_map(self) -> np.ndarray:
        """The points KISS-ICP currently registers against (within max_range of the robot)."""
        with self._odometry_lock:
            return np.asarray(self._odometry.local_map.point_cloud())

    def global_map(self) -> np.ndarray:
        """Every keyframe scan (and a loaded map), voxel-thinned to `map_voxel_size`."""
        from kiss_icp.voxelization import voxel_down_sample

        with self._state_lock:
            chunks = [self._prior_map, *self._map_chunks]
        merged = np.concatenate(chunks) if chunks else np.empty((0, 3))
        if len(merged) == 0:
            return merged
        return np.asarray(voxel_down_sample(merged, self.config.map_voxel_size))

    def trajectory(self) -> tuple[np.ndarray, np.ndarray]:
        with self._state_lock:
            return np.asarray(self._stamps, dtype=np.int64), np.asarray(self._poses).reshape(-1, 4, 4)

    def save_map(self, path: Path) -> int:
        """Writes the global map (binary PLY) and the trajectory (`<stem>.trajectory.csv`); returns points."""
        points = self.global_map()
        path = Path(path)
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            write_ply(path, points)
            stamps, poses = self.trajectory()
            trajectory.write_poses_csv(path.with_suffix(".trajectory.csv"), stamps, poses)
        except OSError as err:
            raise MapFileError(f"{path}: cannot write map: {err.strerror}") from err
        return len(points)

    def load_map(self, path: Path) -> int:
        """Seeds the odometry's local map with a saved map so new scans localise against it."""
        points = read_ply(Path(path))
        with self._odometry_lock, self._state_lock:
            self._odometry.local_map.add_points(points)
            self._prior_map = points
        return len(points)


def _odometry(config: object) -> Any:
    """KISS-ICP's odometry, keeping the points each scan adds to its local map (`map_points`)."""
    from kiss_icp.kiss_icp import KissICP

    class Odometry(KissICP):
        map_points: np.ndarray = np.empty((0, 3))

        def voxelize(self, iframe: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            source, frame_downsample = super().voxelize(iframe)
            self.map_points = np.asarray(frame_downsample)
            return source, frame_downsample

    return Odometry(config=config)
