"""PointCloud2 payloads <-> numpy, independent of which message library carries them.

The generator writes clouds with rosbags types, the bag player republishes their CDR bytes and
the SLAM skillset reads those bytes with rosbags (`cdr_typestore`): all agree on the layout
through these helpers.
Field datatypes follow sensor_msgs/PointField (INT8=1 ... FLOAT64=8).
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from typing import Any

import numpy as np

DATATYPES: dict[int, np.dtype[Any]] = {
    1: np.dtype(np.int8),
    2: np.dtype(np.uint8),
    3: np.dtype(np.int16),
    4: np.dtype(np.uint16),
    5: np.dtype(np.int32),
    6: np.dtype(np.uint32),
    7: np.dtype(np.float32),
    8: np.dtype(np.float64),
}
FLOAT32 = 7
TIME_FIELDS = ("t", "time", "timestamp", "timestamps")


@dataclass(frozen=True)
class FieldSpec:
    name: str
    offset: int
    datatype: int
    count: int = 1


XYZT_FIELDS = (
    FieldSpec("x", 0, FLOAT32),
    FieldSpec("y", 4, FLOAT32),
    FieldSpec("z", 8, FLOAT32),
    FieldSpec("t", 12, FLOAT32),
)
XYZT_POINT_STEP = 16


def encode_xyzt(points: np.ndarray, times: np.ndarray) -> np.ndarray:
    """Packs (N, 3) points and (N,) per-point times into the XYZT_FIELDS layout, as uint8 bytes."""
    record = np.empty(len(points), dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("t", "<f4")])
    record["x"], record["y"], record["z"] = points[:, 0], points[:, 1], points[:, 2]
    record["t"] = times
    return record.view(np.uint8).reshape(-1)


def header(store: Any, stamp_ns: int, frame_id: str) -> Any:
    """A rosbags `std_msgs/msg/Header` stamped `stamp_ns` (nanoseconds since the epoch)."""
    stamp = store.types["builtin_interfaces/msg/Time"](
        sec=stamp_ns // 1_000_000_000, nanosec=stamp_ns % 1_000_000_000
    )
    return store.types["std_msgs/msg/Header"](stamp=stamp, frame_id=frame_id)


def xyzt_cloud(store: Any, header: Any, points: np.ndarray, times: np.ndarray) -> Any:
    """A rosbags `sensor_msgs/msg/PointCloud2` of (N, 3) points with per-point times (XYZT_FIELDS)."""
    return store.types["sensor_msgs/msg/PointCloud2"](
        header=header,
        height=1,
        width=len(points),
        fields=[
            store.types["sensor_msgs/msg/PointField"](
                name=f.name, offset=f.offset, datatype=f.datatype, count=f.count
            )
            for f in XYZT_FIELDS
        ],
        is_bigendian=False,
        point_step=XYZT_POINT_STEP,
        row_step=XYZT_POINT_STEP * len(points),
        data=encode_xyzt(points, times),
        is_dense=True,
    )


def warm_up(store: Any) -> None:
    """Reads one tiny cloud the way a receiver reads every scan. rosbags generates a type's CDR
    reader at its first use (7 ms alone, tens of ms beside a busy mission): a component calls this
    when it starts, so its first scan is not the one that pays."""
    cloud = xyzt_cloud(store, header(store, 0, ""), np.zeros((1, 3)), np.zeros(1))
    message = store.deserialize_cdr(store.serialize_cdr(cloud, cloud.__msgtype__), cloud.__msgtype__)
    decode(message.fields, message.data, message.point_step, message.width, message.height)


def decode(
    fields: list[Any],
    data: bytes | np.ndarray | Any,
    point_step: int,
    width: int,
    height: int,
    is_bigendian: bool = False,
) -> tuple[np.ndarray, np.ndarray | None]:
    """(N, 3) float64 points and per-point times (float64, or None when the cloud has none).

    `fields` are any objects with name/offset/datatype/count attributes (rosbags or rclpy PointField).

    Raises:
        ValueError: the cloud lacks x, y or z, uses an unknown datatype, or its data is too short.
    """
    names, formats, offsets = [], [], []
    for field in fields:
        if field.datatype not in DATATYPES:
            raise ValueError(f"field {field.name!r} has unknown PointField datatype {field.datatype}")
        dtype = DATATYPES[field.datatype].newbyteorder(">" if is_bigendian else "<")
        names.append(field.name)
        formats.append(dtype if field.count <= 1 else (dtype, (field.count,)))
        offsets.append(field.offset)
    missing = {"x", "y", "z"} - set(names)
    if missing:
        raise ValueError(f"point cloud has no field(s) {sorted(missing)}")
    count = width * height
    buffer = np.frombuffer(memoryview(data) if not isinstance(data, np.ndarray) else data, dtype=np.uint8)
    if buffer.size < count * point_step:
        raise ValueError(f"point cloud data holds {buffer.size} bytes, expected {count * point_step}")
    layout = np.dtype({"names": names, "formats": formats, "offsets": offsets, "itemsize": point_step})
    records = buffer[: count * point_step].view(layout)
    # One pass from the message's buffer into the float64 array KISS-ICP takes (no float32 copy).
    points = np.empty((count, 3), dtype=np.float64)
    for column, name in enumerate(("x", "y", "z")):
        points[:, column] = records[name]
    time_name = next((n for n in TIME_FIELDS if n in names), None)
    times = records[time_name].astype(np.float64) if time_name else None
    return points, times


def cdr_typestore() -> Any:
    """rosbags' ROS 2 Jazzy message types, to read CDR bytes taken from a raw subscription: the
    point data comes back as a numpy view on those bytes, where rclpy would copy it into a message."""
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_JAZZY)


def native_bigendian() -> bool:
    return sys.byteorder == "big"
