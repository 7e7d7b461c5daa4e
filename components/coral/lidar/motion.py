"""The sensor's motion along a scene path: a pose (4x4, world from sensor) for any time.

Pure functions of the path and the motion parameters, called by `coral.lidar.sensor` (one pose per
firing column, so scans are skewed as a spinning LiDAR's are) and by `coral.lidar.generating`
(ground-truth poses at the middle of each sweep).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Motion:
    """Constant speed along the path, with a gentle bob in height and a small roll/pitch sway."""

    path: np.ndarray
    speed: float = 1.0
    mount_height: float = 1.2
    bob: float = 0.04
    sway_rad: float = np.deg2rad(1.0)

    @property
    def arc(self) -> np.ndarray:
        steps = np.linalg.norm(np.diff(self.path, axis=0), axis=1)
        return np.concatenate([[0.0], np.cumsum(steps)])

    @property
    def duration(self) -> float:
        return float(self.arc[-1] / self.speed)

    def poses(self, times: np.ndarray) -> np.ndarray:
        """(N, 4, 4) world-from-sensor transforms at `times` (seconds since the start of the path)."""
        times = np.asarray(times, dtype=np.float64)
        arc = self.arc
        s = np.clip(times * self.speed, 0.0, arc[-1])
        x = np.interp(s, arc, self.path[:, 0])
        y = np.interp(s, arc, self.path[:, 1])
        # Heading from a finite difference a little ahead and behind, so it turns smoothly.
        ahead = np.clip(s + 0.3, 0.0, arc[-1])
        behind = np.clip(s - 0.3, 0.0, arc[-1])
        yaw = np.arctan2(
            np.interp(ahead, arc, self.path[:, 1]) - np.interp(behind, arc, self.path[:, 1]),
            np.interp(ahead, arc, self.path[:, 0]) - np.interp(behind, arc, self.path[:, 0]),
        )
        z = self.mount_height + self.bob * np.sin(2 * np.pi * 0.5 * times)
        roll = self.sway_rad * np.sin(2 * np.pi * 0.3 * times)
        pitch = self.sway_rad * np.sin(2 * np.pi * 0.2 * times + 1.0)
        out = np.zeros((len(times), 4, 4))
        out[:, :3, :3] = rotation_zyx(yaw, pitch, roll)
        out[:, 0, 3], out[:, 1, 3], out[:, 2, 3] = x, y, z
        out[:, 3, 3] = 1.0
        return out


def rotation_zyx(yaw: np.ndarray, pitch: np.ndarray, roll: np.ndarray) -> np.ndarray:
    """(N, 3, 3) rotations R = Rz(yaw) Ry(pitch) Rx(roll)."""
    cy, sy = np.cos(yaw), np.sin(yaw)
    cp, sp = np.cos(pitch), np.sin(pitch)
    cr, sr = np.cos(roll), np.sin(roll)
    r = np.empty((len(yaw), 3, 3))
    r[:, 0, 0] = cy * cp
    r[:, 0, 1] = cy * sp * sr - sy * cr
    r[:, 0, 2] = cy * sp * cr + sy * sr
    r[:, 1, 0] = sy * cp
    r[:, 1, 1] = sy * sp * sr + cy * cr
    r[:, 1, 2] = sy * sp * cr - cy * sr
    r[:, 2, 0] = -sp
    r[:, 2, 1] = cp * sr
    r[:, 2, 2] = cp * cr
    return r


def quaternion_from_matrix(rotation: np.ndarray) -> tuple[float, float, float, float]:
    """(x, y, z, w) of a proper 3x3 rotation matrix."""
    m = rotation
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    if trace > 0:
        s = 2.0 * np.sqrt(trace + 1.0)
        w, x = 0.25 * s, (m[2, 1] - m[1, 2]) / s
        y, z = (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        w, x = (m[2, 1] - m[1, 2]) / s, 0.25 * s
        y, z = (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s
    elif m[1, 1] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        w, x = (m[0, 2] - m[2, 0]) / s, (m[0, 1] + m[1, 0]) / s
        y, z = 0.25 * s, (m[1, 2] + m[2, 1]) / s
    else:
        s = 2.0 * np.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        w, x = (m[1, 0] - m[0, 1]) / s, (m[0, 2] + m[2, 0]) / s
        y, z = (m[1, 2] + m[2, 1]) / s, 0.25 * s
    return float(x), float(y), float(z), float(w)


def matrix_from_quaternion(x: float, y: float, z: float, w: float) -> np.ndarray:
    """3x3 rotation of a (possibly unnormalised) quaternion."""
    n = np.sqrt(x * x + y * y + z * z + w * w)
    x, y, z, w = x / n, y / n, z / n, w / n
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )
