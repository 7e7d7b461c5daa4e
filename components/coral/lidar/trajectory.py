"""Trajectory error of an estimate against ground truth: ATE after rigid alignment, and RPE.

Pure functions over (N, 4, 4) pose arrays, plus readers/writers for the CSV pose format both the
generator (ground_truth.csv) and the SLAM skillset (trajectory.csv) use. Called by the demo report,
the tests and the SLAM benchmark, for Coral's run and for KISS-ICP's own pipeline alike.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from coral.lidar.motion import matrix_from_quaternion, quaternion_from_matrix

CSV_HEADER = "stamp_ns,x,y,z,qx,qy,qz,qw"


@dataclass(frozen=True)
class TrajectoryError:
    ate_rmse_m: float  # translation RMSE after the best rigid alignment
    rpe_rmse_m: float  # RMSE of the per-step relative translation error
    pairs: int


def read_poses_csv(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """(stamps_ns, poses) from a CSV in CSV_HEADER format.

    Raises:
        ValueError: naming the file and line of a malformed row.
    """
    stamps: list[int] = []
    poses: list[np.ndarray] = []
    lines = Path(path).read_text().splitlines()
    for number, line in enumerate(lines, start=1):
        if number == 1 and line.startswith("stamp"):
            continue
        if not line.strip():
            continue
        try:
            values = [float(v) for v in line.split(",")]
            if len(values) != 8:
                raise ValueError(f"expected 8 columns, found {len(values)}")
        except ValueError as err:
            raise ValueError(f"{path}:{number}: {err}") from err
        pose = np.eye(4)
        pose[:3, :3] = matrix_from_quaternion(*values[4:8])
        pose[:3, 3] = values[1:4]
        stamps.append(int(values[0]))
        poses.append(pose)
    return np.asarray(stamps, dtype=np.int64), np.asarray(poses).reshape(-1, 4, 4)


def write_poses_csv(path: Path, stamps_ns: np.ndarray, poses: np.ndarray) -> None:
    rows = [CSV_HEADER]
    for stamp, pose in zip(stamps_ns, poses, strict=True):
        qx, qy, qz, qw = quaternion_from_matrix(pose[:3, :3])
        x, y, z = pose[:3, 3]
        rows.append(f"{int(stamp)},{x:.6f},{y:.6f},{z:.6f},{qx:.9f},{qy:.9f},{qz:.9f},{qw:.9f}")
    Path(path).write_text("\n".join(rows) + "\n")


def rigid_alignment(source: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotation R and translation t minimising |R source + t - target| (Kabsch/Umeyama, no scale)."""
    mu_s, mu_t = source.mean(axis=0), target.mean(axis=0)
    covariance = (target - mu_t).T @ (source - mu_s) / len(source)
    u, _, vt = np.linalg.svd(covariance)
    sign = np.eye(3)
    if np.linalg.det(u @ vt) < 0:
        sign[2, 2] = -1.0
    rotation = u @ sign @ vt
    return rotation, mu_t - rotation @ mu_s


def trajectory_error(estimate: np.ndarray, truth: np.ndarray) -> TrajectoryError:
    """Errors of `estimate` against `truth`, both (N, 4, 4) and matched index by index."""
    if len(estimate) != len(truth) or len(estimate) < 2:
        raise ValueError(f"need two equally long trajectories, got {len(estimate)} and {len(truth)} poses")
    est_xyz, true_xyz = estimate[:, :3, 3], truth[:, :3, 3]
    rotation, translation = rigid_alignment(est_xyz, true_xyz)
    aligned = est_xyz @ rotation.T + translation
    ate = float(np.sqrt(np.mean(np.sum((aligned - true_xyz) ** 2, axis=1))))
    est_rel = np.linalg.inv(estimate[:-1]) @ estimate[1:]
    true_rel = np.linalg.inv(truth[:-1]) @ truth[1:]
    delta = np.linalg.inv(true_rel) @ est_rel
    rpe = float(np.sqrt(np.mean(np.sum(delta[:, :3, 3] ** 2, axis=1))))
    return TrajectoryError(ate_rmse_m=ate, rpe_rmse_m=rpe, pairs=len(estimate))


def match_by_stamp(
    est_stamps: np.ndarray, estimate: np.ndarray, true_stamps: np.ndarray, truth: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Keeps the poses whose stamps appear in both trajectories (a skipped scan drops out of both)."""
    index = {int(s): i for i, s in enumerate(true_stamps)}
    pairs = [(i, index[int(s)]) for i, s in enumerate(est_stamps) if int(s) in index]
    if not pairs:
        return np.empty((0, 4, 4)), np.empty((0, 4, 4))
    est_i, true_i = zip(*pairs, strict=True)
    return estimate[list(est_i)], truth[list(true_i)]
