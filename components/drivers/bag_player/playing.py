"""Reads a ROS 2 bag with rosbags and paces its messages at the recorded rate or a multiple of it.

No ROS here: `play` hands each message's raw CDR bytes to a callback (the driver publishes them
unchanged, so no deserialisation is paid), sleeping on a stop event between messages so SIGINT is
honoured at once. Called by `coral_drivers.bag_player.driver` and by the tests.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path


class BagError(ValueError):
    """The bag cannot be opened or lacks the requested topics; the message names the bag."""


@dataclass(frozen=True)
class TopicInfo:
    name: str
    msgtype: str  # e.g. "sensor_msgs/msg/PointCloud2"
    count: int


@dataclass(frozen=True)
class PlayReport:
    messages: int
    duration_s: float
    stopped_early: bool
    per_topic: dict[str, int] = field(default_factory=dict)


def read_topics(bag: Path) -> list[TopicInfo]:
    from rosbags.highlevel import AnyReader, AnyReaderError

    try:
        with AnyReader([Path(bag)]) as reader:
            return [
                TopicInfo(name, info.msgtype or "", info.msgcount) for name, info in reader.topics.items()
            ]
    except (AnyReaderError, OSError) as err:
        raise BagError(f"{bag}: cannot open bag: {err}") from err


def iterate(bag: Path, topics: Sequence[str] = ()) -> Iterator[tuple[str, str, int, bytes]]:
    """Yields (topic, msgtype, timestamp_ns, cdr_bytes) in recorded order.

    Raises:
        BagError: the bag cannot be read, or a requested topic is not in it.
    """
    from rosbags.highlevel import AnyReader, AnyReaderError

    try:
        with AnyReader([Path(bag)]) as reader:
            known = {c.topic for c in reader.connections}
            missing = sorted(set(topics) - known)
            if missing:
                raise BagError(f"{bag}: no topic(s) {missing}; the bag has {sorted(known)}")
            connections = [c for c in reader.connections if not topics or c.topic in topics]
            for connection, stamp, raw in reader.messages(connections=connections):
                yield connection.topic, connection.msgtype, int(stamp), bytes(raw)
    except (AnyReaderError, OSError) as err:
        raise BagError(f"{bag}: cannot read bag: {err}") from err


def play(
    messages: Iterator[tuple[str, str, int, bytes]],
    publish: Callable[[str, str, bytes], None],
    *,
    rate: float = 1.0,
    stop: threading.Event | None = None,
    clock: Callable[[], float] = time.monotonic,
) -> PlayReport:
    """Publishes every message, keeping the recorded spacing divided by `rate` (0: as fast as possible)."""
    stop = stop or threading.Event()
    started = clock()
    first_stamp: int | None = None
    count = 0
    per_topic: dict[str, int] = {}
    for topic, msgtype, stamp, raw in messages:
        if stop.is_set():
            return PlayReport(count, clock() - started, True, per_topic)
        if first_stamp is None:
            first_stamp = stamp
        if rate > 0:
            due = started + (stamp - first_stamp) / 1e9 / rate
            wait = due - clock()
            if wait > 0 and stop.wait(wait):
                return PlayReport(count, clock() - started, True, per_topic)
        publish(topic, msgtype, raw)
        count += 1
        per_topic[topic] = per_topic.get(topic, 0) + 1
    return PlayReport(count, clock() - started, False, per_topic)
