"""The snapshot skillset with `subscribe: on_request`: the first snapshot holds what was published
before it was requested (a bag that played once stays visible), later ones the next messages after
their request, with the topics unsubscribed in between; the process survives many such cycles."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from fixtures.processes import Spawn

from .runtime_processes import STARTUP_S, wait_until

pytestmark = [pytest.mark.ros, pytest.mark.slow]

TOPICS = ["/snapshot_test/a", "/snapshot_test/b"]
CYCLES = 12


def _start_snapshot(spawned: Spawn, env: dict[str, str], tmp_path: Path) -> subprocess.Popen[Any]:
    params = tmp_path / "params.yaml"
    params.write_text(
        "snapshot:\n  ros__parameters:\n"
        f"    topics: {json.dumps(TOPICS)}\n"
        '    types: ["nav_msgs/msg/Odometry", "nav_msgs/msg/Odometry"]\n'
        f"    output_dir: {tmp_path / 'snapshots'}\n"
        "    subscribe: on_request\n"
        "    request_wait_s: 5.0\n"
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


def test_on_request_keeps_what_came_before_the_first_snapshot_and_listens_only_on_request_after(
    ros_env: dict[str, str], spawned: Spawn, tmp_path: Path
) -> None:
    import rclpy
    from nav_msgs.msg import Odometry
    from rclpy.executors import SingleThreadedExecutor
    from std_srvs.srv import Trigger

    process = _start_snapshot(spawned, ros_env, tmp_path)
    log = tmp_path / "snapshot.log"
    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        node = rclpy.create_node("snapshot_test", context=context)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        publishers = [node.create_publisher(Odometry, topic, 10) for topic in TOPICS]
        client = node.create_client(Trigger, "/snapshot/latest")

        def publish(sec: int) -> None:
            for publisher in publishers:
                message = Odometry()
                message.header.stamp.sec = sec
                publisher.publish(message)

        def call(while_waiting: Callable[[], None] = lambda: None) -> tuple[bool, dict[str, Any]]:
            future = client.call_async(Trigger.Request())
            deadline = time.monotonic() + 30
            while not future.done() and time.monotonic() < deadline:
                while_waiting()
                executor.spin_once(timeout_sec=0.05)
            assert future.done(), f"no snapshot response within 30 s; log:\n{log.read_text()}"
            response = future.result()
            return response.success, json.loads(response.message)

        assert client.wait_for_service(timeout_sec=STARTUP_S)
        wait_until(
            lambda: all(p.get_subscription_count() == 1 for p in publishers),
            STARTUP_S,
            "the skillset to listen",
        )
        # Published once, before any request, and never again: the first snapshot still holds it
        # (a request made before the message arrived fails at once, and the next one is made).
        publish(1)
        first = wait_until(
            lambda: (result := call())[0] and result[1],
            15,
            "a first snapshot of the messages published before it was requested",
        )
        assert first["stamps"] == [1_000_000_000, 1_000_000_000]
        wait_until(
            lambda: all(p.get_subscription_count() == 0 for p in publishers),
            10,
            "the skillset to unsubscribe after its first snapshot",
        )

        # Later snapshots subscribe for their request and hold messages sent after it.
        for cycle in range(CYCLES):
            sec = 10 + cycle
            success, payload = call(lambda sec=sec: publish(sec))
            assert success and payload["stamps"] == [sec * 1_000_000_000] * 2, (cycle, payload)
            assert process.poll() is None, log.read_text()
        wait_until(
            lambda: all(p.get_subscription_count() == 0 for p in publishers),
            10,
            "the skillset to unsubscribe between requests",
        )
        assert process.poll() is None, log.read_text()
        assert "Traceback" not in log.read_text(), log.read_text()
        node.destroy_node()
    finally:
        rclpy.shutdown(context=context)
