"""A `RawStream` hands each message's CDR bytes to its callback on its own thread, apart from the
component's executor, in order and without loss over a burst, and `close` ends that thread."""

from __future__ import annotations

import threading

import pytest
from coral_testbed.waiting import wait_for

pytestmark = pytest.mark.ros

BURST = 200


def test_a_raw_stream_receives_a_burst_in_order_on_its_own_thread(ros_env: dict[str, str]) -> None:
    import rclpy
    from coral.sdk.streams import RawStream
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
    from rclpy.serialization import deserialize_message
    from std_msgs.msg import String

    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        owner = rclpy.create_node("stream_owner", namespace="/robot", context=context)
        talker = rclpy.create_node("stream_talker", context=context)
        qos = QoSProfile(depth=BURST, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST)
        received: list[bytes] = []
        threads: set[str] = set()
        all_in = threading.Event()

        def on_message(raw: bytes) -> None:
            received.append(raw)
            threads.add(threading.current_thread().name)
            if len(received) == BURST:
                all_in.set()

        stream = RawStream(owner, String, "chatter", qos, on_message, suffix="points")
        assert stream.topic == "/robot/chatter"
        # The owner's own executor has nothing to wait on for this stream.
        assert list(owner.subscriptions) == []
        publisher = talker.create_publisher(String, "/robot/chatter", qos)
        wait_for(
            lambda: publisher.get_subscription_count() > 0, timeout=20, message="the stream to be discovered"
        )
        for index in range(BURST):
            publisher.publish(String(data=f"scan {index}"))
        assert all_in.wait(20), f"{len(received)} of {BURST} messages arrived"
        assert [deserialize_message(raw, String).data for raw in received] == [
            f"scan {index}" for index in range(BURST)
        ]
        assert threads == {"points-stream"}
        stream.close()
        assert not any(t.name == "points-stream" for t in threading.enumerate())
        owner.destroy_node()
        talker.destroy_node()
    finally:
        rclpy.shutdown(context=context)
