"""Per-topic buffers of raw (CDR) messages and the choice of a snapshot: latest or synchronised.

Pure Python, no ROS: the skillset node feeds `TopicBuffer.add` from raw subscriptions; the
choice functions return which buffered message of each topic makes up the snapshot.
"""

from __future__ import annotations

import collections
import struct
from dataclasses import dataclass


@dataclass(frozen=True)
class Sample:
    stamp_ns: int  # header stamp when the message starts with a std_msgs/Header, else receive time
    raw: bytes


class TopicBuffer:
    def __init__(self, topic: str, msgtype: str, has_header: bool, size: int) -> None:
        self.topic, self.msgtype, self.has_header = topic, msgtype, has_header
        self.samples: collections.deque[Sample] = collections.deque(maxlen=size)

    def add(self, raw: bytes, received_ns: int) -> None:
        stamp = header_stamp(raw) if self.has_header else None
        self.samples.append(Sample(stamp if stamp is not None else received_ns, raw))


def header_stamp(raw: bytes) -> int | None:
    """Stamp of a CDR message whose first field is a std_msgs/Header (sec int32, nanosec uint32)."""
    if len(raw) < 12:
        return None
    little = raw[1] == 1  # encapsulation kind: 0x0001 CDR_LE, 0x0000 CDR_BE
    sec, nanosec = struct.unpack("<iI" if little else ">iI", raw[4:12])
    return sec * 1_000_000_000 + nanosec


def choose_latest(buffers: list[TopicBuffer]) -> list[Sample] | str:
    """The newest sample of every topic, or the reason there is none."""
    empty = [b.topic for b in buffers if not b.samples]
    if empty:
        return f"no message yet on {', '.join(empty)}"
    return [b.samples[-1] for b in buffers]


def choose_synchronized(buffers: list[TopicBuffer], slop_ns: int) -> list[Sample] | str:
    """The newest set with one sample per topic whose stamps all lie within `slop_ns` of the first topic's."""
    empty = [b.topic for b in buffers if not b.samples]
    if empty:
        return f"no message yet on {', '.join(empty)}"
    first, others = buffers[0], buffers[1:]
    for anchor in reversed(first.samples):
        chosen = [anchor]
        for buffer in others:
            best = min(buffer.samples, key=lambda s: abs(s.stamp_ns - anchor.stamp_ns))
            if abs(best.stamp_ns - anchor.stamp_ns) > slop_ns:
                break
            chosen.append(best)
        else:
            return chosen
    return f"no messages within {slop_ns / 1e9:g} s of each other on {', '.join(b.topic for b in buffers)}"
