"""The snapshot skillset's choice of messages: latest per topic, or the newest set within the slop."""

from __future__ import annotations

import struct

from coral_skillsets.snapshot.buffering import TopicBuffer, choose_latest, choose_synchronized, header_stamp


def _stamped(sec: int, nanosec: int, little: bool = True) -> bytes:
    encapsulation = b"\x00\x01\x00\x00" if little else b"\x00\x00\x00\x00"
    return encapsulation + struct.pack("<iI" if little else ">iI", sec, nanosec) + b"payload"


def test_the_header_stamp_is_read_from_raw_cdr_in_either_byte_order() -> None:
    assert header_stamp(_stamped(5, 7)) == 5_000_000_007
    assert header_stamp(_stamped(5, 7, little=False)) == 5_000_000_007
    assert header_stamp(b"\x00\x01") is None


def _buffer(topic: str, stamps: list[tuple[int, int]]) -> TopicBuffer:
    buffer = TopicBuffer(topic, "x/msg/Y", has_header=True, size=10)
    for sec, nanosec in stamps:
        buffer.add(_stamped(sec, nanosec), received_ns=0)
    return buffer


def test_latest_takes_the_newest_message_of_each_topic_and_names_empty_ones() -> None:
    points, truth = _buffer("/points", [(1, 0), (2, 0)]), _buffer("/truth", [(1, 5)])
    assert [s.stamp_ns for s in choose_latest([points, truth])] == [2_000_000_000, 1_000_000_005]
    assert choose_latest([points, _buffer("/empty", [])]) == "no message yet on /empty"


def test_synchronized_takes_the_newest_set_within_the_slop() -> None:
    points = _buffer("/points", [(1, 0), (2, 0), (3, 0)])
    truth = _buffer("/truth", [(1, 1000), (2, 2000)])  # nothing near t=3
    chosen = choose_synchronized([points, truth], slop_ns=10_000)
    assert [s.stamp_ns for s in chosen] == [2_000_000_000, 2_000_002_000]
    assert "no messages within" in choose_synchronized([points, truth], slop_ns=10)
