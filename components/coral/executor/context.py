"""The executor's ROS side: one node spun on a background thread, shared by every behavior.

Built by `coral.executor.running`; passed to `bt.build_tree(context=...)` so behaviors reach
it as `self.context` (see `coral.sdk.calls.CallContext`). ROS callbacks only record results and
wake the tree; the tick thread never waits on ROS I/O.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from coral.executor.health import HealthMonitor
from coral.executor.wakeups import WakeSchedule
from coral.sdk import dds, topics
from coral.sdk.spinning import Spinner


class _Latest:
    """Newest message of one subscription with its monotonic receive time."""

    def __init__(self) -> None:
        self._value: tuple[Any, float] = (None, 0.0)

    def store(self, message: Any) -> None:
        self._value = (message, time.monotonic())

    def latest(self) -> tuple[Any, float]:
        return self._value


class ExecutorContext:
    """ROS node, client and subscription caches, component health, and failure notes for the status."""

    def __init__(
        self,
        *,
        node_name: str,
        hostname: str,
        params_file: Path | None = None,
        wake_up: Callable[[], None] = lambda: None,
    ) -> None:
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node
        from rclpy.qos import QoSProfile, ReliabilityPolicy
        from rclpy.signals import SignalHandlerOptions
        from std_msgs.msg import String

        if not rclpy.ok():
            dds.use_coral_profile()
            rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
        cli_args = ["--ros-args", "--params-file", str(params_file)] if params_file else None
        self.node: Any = Node(
            node_name, cli_args=cli_args, automatically_declare_parameters_from_overrides=True
        )
        self.hostname = hostname
        self.wake_up = wake_up
        self.health = HealthMonitor(time.monotonic)
        self.wakeups = WakeSchedule()
        self.failures: dict[str, str] = {}
        self._clients: dict[tuple[Any, str], Any] = {}
        self._caches: dict[tuple[Any, str, bool], _Latest] = {}
        self._publishers: dict[tuple[Any, str, bool], Any] = {}
        self._subscriptions: list[Any] = []
        self._lock = threading.Lock()
        self._string = String
        self.node.create_subscription(
            String, topics.HEARTBEAT_TOPIC, self._on_heartbeat, QoSProfile(depth=50)
        )
        self._cancel_publisher = self.node.create_publisher(
            String, topics.CANCEL_TOPIC, QoSProfile(depth=50, reliability=ReliabilityPolicy.RELIABLE)
        )
        self.coordination: Any = None
        self._executor = SingleThreadedExecutor()
        self._executor.add_node(self.node)
        self._spinner = Spinner(self._executor, "ros-spin").start()

    def _on_heartbeat(self, message: Any) -> None:
        heartbeat = topics.Heartbeat.decode(message.data)
        if heartbeat is not None:
            self.health.observe(heartbeat)
            if heartbeat.state == "stopping":
                self.wake_up()  # calls into it fail at once, not at the tree's next tick

    # coral.sdk.calls.CallContext
    def wake_at(self, when: float) -> int:
        return self.wakeups.add(when)

    def cancel_wake(self, token: int) -> None:
        self.wakeups.cancel(token)

    def service_client(self, srv_type: Any, service: str) -> Any:
        key = (srv_type, service)
        with self._lock:
            client = self._clients.get(key)
            if client is None:
                client = self.node.create_client(srv_type, service)
                self._clients[key] = client
            return client

    def _qos(self, latched: bool) -> Any:
        from rclpy.qos import DurabilityPolicy, QoSProfile

        durability = DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE
        return QoSProfile(depth=10, durability=durability)

    def subscription_cache(self, msg_type: Any, topic: str, latched: bool = False) -> _Latest:
        key = (msg_type, topic, latched)
        with self._lock:
            cache = self._caches.get(key)
            if cache is None:
                cache = _Latest()

                def receive(message: Any, cache: _Latest = cache) -> None:
                    cache.store(message)
                    self.wake_up()

                self._subscriptions.append(
                    self.node.create_subscription(msg_type, topic, receive, self._qos(latched))
                )
                self._caches[key] = cache
            return cache

    def publisher(self, msg_type: Any, topic: str, latched: bool = False) -> Any:
        key = (msg_type, topic, latched)
        with self._lock:
            publisher = self._publishers.get(key)
            if publisher is None:
                publisher = self.node.create_publisher(msg_type, topic, self._qos(latched))
                self._publishers[key] = publisher
            return publisher

    def component_failure(self, component: str) -> str | None:
        return self.health.refuse_call(component)

    def publish_cancel(self, service: str) -> None:
        request = topics.CancelRequest(service, self.node.get_fully_qualified_name())
        self._cancel_publisher.publish(self._string(data=request.encode()))

    def note_failure(self, behavior: Any, message: str) -> None:
        path = str(getattr(behavior, "path", getattr(behavior, "name", "?")))
        with self._lock:
            self.failures[path] = message

    def failure_message(self, path: str) -> str:
        """Why the node at `path` failed, as noted for this failure; read once, so a later failure
        of the same node that noted nothing (a refusal from the skillset, say) does not repeat an
        old reason, such as a skillset that was unavailable and has since come back."""
        with self._lock:
            return self.failures.pop(path, "")

    def flush(self, timeout_s: float = 1.0) -> None:
        """Waits (bounded) until peers acknowledged what we published, so a cancel or a trigger
        acknowledgement sent in the last tick is not lost when the process exits right after."""
        from rclpy.duration import Duration

        with self._lock:
            publishers = [self._cancel_publisher, *self._publishers.values()]
        if self.coordination is not None:
            publishers += self.coordination.publishers()
        deadline = time.monotonic() + timeout_s
        for publisher in publishers:
            remaining = max(0.0, deadline - time.monotonic())
            publisher.wait_for_all_acked(Duration(nanoseconds=int(remaining * 1e9)))

    def shutdown(self) -> None:
        import rclpy

        self.flush()
        # rclpy's Executor.shutdown destroys its guard condition without waiting for a spinning
        # thread (Jazzy), which can abort the process (exit 134) after the mission succeeded; so the
        # spin thread is stopped and joined first.
        self._spinner.stop(timeout_s=2.0)
        self._executor.shutdown(timeout_sec=1.0)
        self.node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
