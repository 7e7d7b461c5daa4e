"""Coral's FastDDS profile loads cleanly in the real rmw_fastrtps_cpp of a component process, and
talking over it works; a profile FastDDS cannot parse says so on stderr, which this would catch."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

pytestmark = pytest.mark.ros

PROCESS = textwrap.dedent(
    """
    import os, threading
    from coral.sdk import dds
    assert dds.use_coral_profile()
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from std_msgs.msg import String
    rclpy.init()
    node = rclpy.create_node("profile_probe")
    qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
    got = threading.Event()
    node.create_subscription(String, "/profile_probe", lambda m: got.set(), qos)
    publisher = node.create_publisher(String, "/profile_probe", qos)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    for _ in range(200):
        publisher.publish(String(data="hello"))
        executor.spin_once(timeout_sec=0.05)
        if got.is_set():
            break
    print("profile", os.environ["FASTRTPS_DEFAULT_PROFILES_FILE"])
    print("received", got.is_set())
    rclpy.shutdown()
    """
)


def test_the_profile_parses_and_a_message_goes_through(ros_env: dict[str, str]) -> None:
    from coral.sdk import dds

    env = {k: v for k, v in ros_env.items() if not k.endswith("_DEFAULT_PROFILES_FILE")}
    done = subprocess.run(
        [sys.executable, "-c", PROCESS], env=env, capture_output=True, text=True, timeout=60, check=False
    )
    assert done.returncode == 0, done.stderr
    assert "XMLPARSER" not in done.stderr, done.stderr
    assert f"profile {dds.PROFILE}" in done.stdout
    assert "received True" in done.stdout, done.stdout + done.stderr
