"""A high-rate sensor stream taken apart from a component's executor.

A component's node is spun by rclpy's multi-threaded executor, which rebuilds its wait set in
Python and hands each message to a worker thread: about a third of a millisecond of Python per
message, under the same interpreter lock as the component's own work. For a LiDAR or camera stream
of tens of large messages a second, that is CPU taken from the work the stream feeds (the SLAM
mission measures it, `make bench-slam`). A `RawStream` subscribes on a node of its own, spun on one
thread by rclpy's C++ events executor, and hands the message's CDR bytes to the callback without
deserialising them: the only Python left per message is the callback itself.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

from rclpy.node import Node
from rclpy.qos import QoSProfile


class RawStream:
    """Subscribes `topic` (resolved as `owner` would) on a node named `<owner>_<suffix>`; each
    message's CDR bytes go to `callback` on the stream's own thread. `close` ends it."""

    def __init__(
        self,
        owner: Node,
        msg_type: Any,
        topic: str,
        qos: QoSProfile,
        callback: Callable[[bytes], None],
        suffix: str = "stream",
    ) -> None:
        from rclpy.experimental import EventsExecutor

        self._stop = threading.Event()
        self._node = Node(
            f"{owner.get_name()}_{suffix}",
            namespace=owner.get_namespace(),
            context=owner.context,
            enable_rosout=False,
            start_parameter_services=False,
        )
        self.topic = owner.resolve_topic_name(topic)
        self._node.create_subscription(msg_type, self.topic, callback, qos, raw=True)
        self._executor = EventsExecutor(context=owner.context)
        self._executor.add_node(self._node)
        self._thread = threading.Thread(target=self._spin, name=f"{suffix}-stream", daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        # Bounded waits, so `close` is honoured within one of them.
        while not self._stop.is_set() and self._node.context.ok():
            self._executor.spin_once(timeout_sec=0.1)

    def close(self) -> None:
        self._stop.set()
        self._executor.wake()
        self._thread.join(timeout=5.0)
        self._executor.shutdown()
        self._node.destroy_node()
