"""The SLAM map file: binary little-endian PLY with float32 x, y, z per point.

Written by the SLAM skillset (`coral_skillsets.slam.core`) and read back by it (a prior map), by
the demo's report and its picture (`coral.lidar.demo`, `coral.lidar.picture`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np


class MapFileError(ValueError):
    """A map file cannot be read or written; the message names the file."""


def write_ply(path: Path, points: np.ndarray) -> None:
    """Binary little-endian PLY with float32 x, y, z, written aside then renamed."""
    header = (
        "ply\nformat binary_little_endian 1.0\ncomment coral slam map\n"
        f"element vertex {len(points)}\nproperty float x\nproperty float y\nproperty float z\nend_header\n"
    )
    staging = path.with_name(f".{path.name}.tmp")
    with staging.open("wb") as handle:
        handle.write(header.encode("ascii"))
        handle.write(np.asarray(points, dtype="<f4").tobytes())
    staging.replace(path)


def read_ply(path: Path) -> np.ndarray:
    """Reads what `write_ply` writes (binary little-endian float32 x, y, z)."""
    try:
        raw = path.read_bytes()
    except OSError as err:
        raise MapFileError(f"{path}: cannot read map: {err.strerror}") from err
    marker = b"end_header\n"
    end = raw.find(marker)
    if not raw.startswith(b"ply\n") or end < 0:
        raise MapFileError(f"{path}: not a PLY file")
    header = raw[:end].decode("ascii", errors="replace").splitlines()
    if "format binary_little_endian 1.0" not in header:
        raise MapFileError(f"{path}: only binary little-endian PLY maps are supported")
    counts = [line.split()[-1] for line in header if line.startswith("element vertex")]
    properties = [line for line in header if line.startswith("property")]
    if not counts or properties != ["property float x", "property float y", "property float z"]:
        raise MapFileError(f"{path}: expected one vertex element with float x, y, z")
    count = int(counts[0])
    body = raw[end + len(marker) :]
    if len(body) < count * 12:
        raise MapFileError(f"{path}: truncated: {count} vertices declared, {len(body) // 12} present")
    return np.frombuffer(body[: count * 12], dtype="<f4").reshape(count, 3).astype(np.float64)
