"""The snapshot skillset with `subscribe: on_request`: the first snapshot holds what was published
before it was requested (a bag that played once stays visible), or, asked before the data flows,
the first messages that arrive; later ones the next messages after their request, with the topics
unsubscribed in between; the process survives many such cycles."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest
from fixtures.processes import Spawn

from .runtime_processes import STARTUP_S, wait_until

pytestmark = [pytest.mark.ros, pytest.mark.slow]

TOPICS = ["/snapshot_test/a", "/snapshot_test/b"]
CYCLES = 12


def _start_snapshot(
    spawned: Spawn, env: dict[str, str], tmp_path: Path, request_wait_s: float = 5.0
) -> subprocess.Popen[Any]:
    tmp_path.mkdir(parents=True, exist_ok=True)
    params = tmp_path / "params.yaml"
    params.write_text(
        "snapshot:\n  ros__parameters:\n"
        f"    topics: {json.dumps(TOPICS)}\n"
        '    types: ["nav_msgs/msg/Odometry", "nav_msgs/msg/Odometry"]\n'
        f"    output_dir: {tmp_path / 'snapshots'}\n"
        "    subscribe: on_request\n"
        f"    request_wait_s: {request_wait_s}\n"
    )
    plugins, log = tmp_path / "plugins", tmp_path / "snapshot.log"
    args = [
        sys.executable,
        "-m",
        "coral_skillsets.snapshot",
        "--plugins",
        str(plugins),
        "--params",
        str(params),
    ]
    process = spawned(args, env=env, stdout=log.open("w"), stderr=subprocess.STDOUT)
    ready = plugins / "snapshot" / "ready"
    wait_until(lambda: ready.exists() or process.poll() is not None, STARTUP_S, str(ready))
    assert process.poll() is None, log.read_text()
    return process


class _Peer:
    """The other side of the skillset: publishes both topics and asks for snapshots."""

    def __init__(self, node: Any, executor: Any, log: Path) -> None:
        from nav_msgs.msg import Odometry
        from std_srvs.srv import Trigger

        self._odometry, self._trigger = Odometry, Trigger
        self._executor, self._log = executor, log
        self.publishers = [node.create_publisher(Odometry, topic, 10) for topic in TOPICS]
        self.client = node.create_client(Trigger, "/snapshot/latest")
        assert self.client.wait_for_service(timeout_sec=STARTUP_S)

    def publish(self, sec: int) -> None:
        for publisher in self.publishers:
            message = self._odometry()
            message.header.stamp.sec = sec
            publisher.publish(message)

    def call(self, while_waiting: Callable[[], None] = lambda: None) -> tuple[bool, dict[str, Any]]:
        future = self.client.call_async(self._trigger.Request())
        deadline = time.monotonic() + 30
        while not future.done() and time.monotonic() < deadline:
            while_waiting()
            self._executor.spin_once(timeout_sec=0.05)
        assert future.done(), f"no snapshot response within 30 s; log:\n{self._log.read_text()}"
        response = future.result()
        return response.success, json.loads(response.message)

    def wait_for_subscribers(self, count: int, timeout_s: float, what: str) -> None:
        wait_until(lambda: all(p.get_subscription_count() == count for p in self.publishers), timeout_s, what)


@contextmanager
def _peer(ros_env: dict[str, str], log: Path) -> Iterator[_Peer]:
    import rclpy
    from rclpy.executors import SingleThreadedExecutor

    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        node = rclpy.create_node("snapshot_test", context=context)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        yield _Peer(node, executor, log)
        node.destroy_node()
    finally:
        rclpy.shutdown(context=context)


def test_on_request_keeps_what_came_before_the_first_snapshot_and_listens_only_on_request_after(
    ros_env: dict[str, str], spawned: Spawn, tmp_path: Path
) -> None:
    process = _start_snapshot(spawned, ros_env, tmp_path)
    log = tmp_path / "snapshot.log"
    with _peer(ros_env, log) as peer:
        peer.wait_for_subscribers(1, STARTUP_S, "the skillset to listen")
        # Published once, before any request, and never again: the first snapshot still holds it.
        peer.publish(1)
        first = wait_until(
            lambda: (result := peer.call())[0] and result[1],
            15,
            "a first snapshot of the messages published before it was requested",
        )
        assert first["stamps"] == [1_000_000_000, 1_000_000_000]
        peer.wait_for_subscribers(0, 10, "the skillset to unsubscribe after its first snapshot")

        # Later snapshots subscribe for their request and hold messages sent after it.
        for cycle in range(CYCLES):
            sec = 10 + cycle
            success, payload = peer.call(lambda sec=sec: peer.publish(sec))
            assert success and payload["stamps"] == [sec * 1_000_000_000] * 2, (cycle, payload)
            assert process.poll() is None, log.read_text()
        peer.wait_for_subscribers(0, 10, "the skillset to unsubscribe between requests")
    assert process.poll() is None, log.read_text()
    assert "Traceback" not in log.read_text(), log.read_text()


def test_a_first_snapshot_asked_before_the_data_flows_gets_the_first_messages_then_stops_listening(
    ros_env: dict[str, str], spawned: Spawn, tmp_path: Path
) -> None:
    """A mission asks for its first snapshot at once; it is answered when the data arrives, and
    the skillset stops receiving the stream then, not at a later retry. A first request that
    times out keeps the skillset listening, so what is published before the retry is kept."""
    process = _start_snapshot(spawned, ros_env, tmp_path, request_wait_s=1.0)
    log = tmp_path / "snapshot.log"
    with _peer(ros_env, log) as peer:
        peer.wait_for_subscribers(1, STARTUP_S, "the skillset to listen")
        success, payload = peer.call()
        assert not success and "no message yet" in payload["error"], payload
        # Had it stopped listening, this message would be lost and no retry would get a snapshot.
        peer.publish(2)
        first = wait_until(
            lambda: (result := peer.call())[0] and result[1],
            15,
            "a snapshot of what came between two requests",
        )
        assert first["stamps"] == [2_000_000_000] * 2
    assert "Traceback" not in log.read_text(), log.read_text()
    process.terminate()  # the next skillset serves the same service names
    process.wait(timeout=30)

    process = _start_snapshot(spawned, ros_env, tmp_path / "asked-first", request_wait_s=10.0)
    log = tmp_path / "asked-first" / "snapshot.log"
    with _peer(ros_env, log) as peer:
        peer.wait_for_subscribers(1, STARTUP_S, "the second skillset to listen")
        published_at: list[float] = []

        def publish_after_a_while() -> None:
            # The request is made with nothing published; the data starts flowing while it waits.
            if not published_at:
                published_at.append(time.monotonic())
            if time.monotonic() - published_at[0] > 0.5:
                peer.publish(3)

        success, payload = peer.call(publish_after_a_while)
        assert success and payload["stamps"] == [3_000_000_000] * 2, payload
        peer.wait_for_subscribers(0, 10, "the skillset to unsubscribe once its first snapshot was saved")
    assert process.poll() is None, log.read_text()
    assert "Traceback" not in log.read_text(), log.read_text()
