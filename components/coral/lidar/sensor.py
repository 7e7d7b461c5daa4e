"""A spinning multi-beam LiDAR ray-cast against a `Scene`, vectorised with numpy.

Each sweep fires `columns` azimuth columns of `beams` lasers; every column is fired from the pose
the sensor has at that instant, so a moving sensor produces the skewed scans real LiDARs produce,
and each point carries its time offset within the sweep (what KISS-ICP's deskewing needs).
Called by `coral.lidar.generating`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from coral.lidar.motion import Motion
from coral.lidar.scene import Scene


@dataclass(frozen=True)
class SensorModel:
    """Beam layout, sweep rate, range limits and noise of the simulated LiDAR."""

    beams: int = 16
    columns: int = 1024
    fov_up_deg: float = 15.0
    fov_down_deg: float = -15.0
    rate_hz: float = 10.0
    max_range: float = 40.0
    min_range: float = 0.3
    range_noise: float = 0.01
    dropout: float = 0.01

    @property
    def period(self) -> float:
        return 1.0 / self.rate_hz

    def local_directions(self) -> tuple[np.ndarray, np.ndarray]:
        """Unit ray directions (columns, beams, 3) in the sensor frame, and column time offsets."""
        elevation = np.deg2rad(np.linspace(self.fov_down_deg, self.fov_up_deg, self.beams))
        azimuth = 2 * np.pi * np.arange(self.columns) / self.columns
        az, el = np.meshgrid(azimuth, elevation, indexing="ij")
        directions = np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], axis=-1)
        offsets = np.arange(self.columns) * (self.period / self.columns)
        return directions, offsets


@dataclass(frozen=True)
class Sweep:
    """One scan: points in the sensor frame at each point's own firing time, and those times."""

    points: np.ndarray  # (N, 3) float32
    times: np.ndarray  # (N,) float32 seconds since the sweep started


def cast_ranges(scene: Scene, origins: np.ndarray, directions: np.ndarray, max_range: float) -> np.ndarray:
    """Distance along each unit ray to the first wall, floor or ceiling (inf if beyond `max_range`).

    Args:
        origins: (R, 3) ray origins in the world frame.
        directions: (R, 3) unit directions in the world frame.
    """
    ranges = np.full(len(origins), np.inf)
    dz = directions[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        floor = np.where(dz < 0, -origins[:, 2] / dz, np.inf)
        ceiling = np.where(dz > 0, (scene.height - origins[:, 2]) / dz, np.inf)
    ranges = np.minimum(ranges, np.minimum(floor, ceiling))

    seg = scene.segments
    p1, edge = seg[:, :2], seg[:, 2:] - seg[:, :2]
    ox, oy = origins[:, 0:1], origins[:, 1:2]
    dx, dy = directions[:, 0:1], directions[:, 1:2]
    # Solve o + t*d = p1 + u*e for every (ray, segment) pair; t is the 3D range since d is unit length.
    denom = dx * edge[None, :, 1] - dy * edge[None, :, 0]
    wx, wy = p1[None, :, 0] - ox, p1[None, :, 1] - oy
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (wx * edge[None, :, 1] - wy * edge[None, :, 0]) / denom
        u = (wx * dy - wy * dx) / denom
    hit = (np.abs(denom) > 1e-12) & (t > 1e-6) & (u >= 0.0) & (u <= 1.0)
    t = np.where(hit, t, np.inf).min(axis=1)
    hit_z = origins[:, 2] + t * dz
    t = np.where((hit_z >= 0.0) & (hit_z <= scene.height), t, np.inf)
    ranges = np.minimum(ranges, t)
    ranges[ranges > max_range] = np.inf
    return ranges


def sweep(
    scene: Scene,
    motion: Motion,
    sensor: SensorModel,
    start_time: float,
    rng: np.random.Generator,
    chunk_columns: int = 128,
) -> Sweep:
    """Ray-casts one sweep starting at `start_time` (seconds along the path)."""
    local, offsets = sensor.local_directions()
    poses = motion.poses(start_time + offsets)
    points: list[np.ndarray] = []
    times: list[np.ndarray] = []
    # Chunks of columns bound the (rays x segments) intermediate arrays to a few tens of MB.
    for first in range(0, sensor.columns, chunk_columns):
        block = slice(first, first + chunk_columns)
        rot, pos = poses[block, :3, :3], poses[block, :3, 3]
        dirs_local = local[block]
        dirs_world = np.einsum("cij,cbj->cbi", rot, dirs_local).reshape(-1, 3)
        origins = np.repeat(pos, sensor.beams, axis=0)
        ranges = cast_ranges(scene, origins, dirs_world, sensor.max_range)
        ranges = ranges + rng.normal(0.0, sensor.range_noise, ranges.shape)
        keep = (
            np.isfinite(ranges) & (ranges > sensor.min_range) & (rng.random(ranges.shape) >= sensor.dropout)
        )
        points.append((dirs_local.reshape(-1, 3) * ranges[:, None])[keep])
        times.append(np.repeat(offsets[block], sensor.beams)[keep])
    return Sweep(
        points=np.concatenate(points).astype(np.float32),
        times=np.concatenate(times).astype(np.float32),
    )
