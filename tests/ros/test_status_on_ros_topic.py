"""On-robot tools see the executor's status on a ROS topic, down to the halt on shutdown."""

from __future__ import annotations

import json
import signal
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fixtures.processes import Spawn

from .runtime_processes import finish, start_executor, wait_until, write_tree

pytestmark = [pytest.mark.ros, pytest.mark.slow]


@pytest.fixture
def status_listener(ros_env: dict[str, str]) -> Iterator[list[dict[str, Any]]]:
    """Records received on /coral/tree_status by a node in this test process (own rclpy context)."""
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import DurabilityPolicy, QoSProfile
    from std_msgs.msg import String

    received: list[dict[str, Any]] = []
    context = Context()
    rclpy.init(context=context)
    node = rclpy.create_node("status_listener", context=context)
    qos = QoSProfile(depth=10, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    node.create_subscription(String, "/coral/tree_status", lambda m: received.append(json.loads(m.data)), qos)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    spinner.start()
    try:
        yield received
    finally:
        executor.shutdown(timeout_sec=2)
        node.destroy_node()
        rclpy.shutdown(context=context)
        spinner.join(timeout=5)


def test_status_and_the_final_halt_are_published_on_the_status_topic(
    tmp_path: Path, ros_env: dict[str, str], spawned: Spawn, status_listener: list[dict[str, Any]]
) -> None:
    plugins = tmp_path / "plugins"
    plugins.mkdir()
    tree = write_tree(tmp_path / "tree.xml", '    <WaitForRemoteTrigger process_identifier="never"/>')
    log = tmp_path / "executor.log"
    executor = start_executor(spawned, ros_env, tree, plugins, tmp_path / "status.jsonl", log)

    def running_seen() -> bool:
        return any(r["event"] == "status" and r["root_status"] == "RUNNING" for r in list(status_listener))

    wait_until(running_seen, 60, "a RUNNING status on /coral/tree_status")
    executor.send_signal(signal.SIGINT)
    assert finish(executor, 30, log) == 128 + signal.SIGINT, log.read_text()
    wait_until(
        lambda: any(r["event"] == "finished" for r in list(status_listener)), 10, "the finished record"
    )
    finished = [r for r in status_listener if r["event"] == "finished"]
    assert finished[-1]["root_status"] == "HALTED"
    assert not any(r["event"] == "transition" for r in status_listener), "transitions stay off the topic"
