"""Coral's FastDDS profiles load cleanly in the real rmw_fastrtps_cpp of a component process, and
talking over them works; a profile FastDDS cannot parse says so on stderr, which this would catch.
The large-data profile's segment is the one the process maps, and a scan-sized message crosses it."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

pytestmark = pytest.mark.ros

PROCESS = textwrap.dedent(
    """
    import os, sys, threading
    from coral.sdk import dds
    assert dds.use_coral_profile(large_messages=sys.argv[1] == "large")
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from std_msgs.msg import String
    rclpy.init()
    node = rclpy.create_node("profile_probe")
    qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
    got = threading.Event()
    size = int(sys.argv[2])
    node.create_subscription(String, "/profile_probe", lambda m: len(m.data) == size and got.set(), qos)
    publisher = node.create_publisher(String, "/profile_probe", qos)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    for _ in range(200):
        publisher.publish(String(data="x" * size))
        executor.spin_once(timeout_sec=0.05)
        if got.is_set():
            break
    print("profile", os.environ["FASTRTPS_DEFAULT_PROFILES_FILE"])
    print("received", got.is_set())
    # This process's own segment: FastDDS names each one after a participant, and maps the other
    # processes' segments too, so the largest mapping of a segment here is the one it made.
    sizes = {}
    for line in open("/proc/self/maps"):
        fields = line.split()
        if len(fields) == 6 and fields[5].startswith("/dev/shm/fastrtps_") and "port" not in fields[5]:
            start, end = (int(value, 16) for value in fields[0].split("-"))
            sizes[fields[5]] = sizes.get(fields[5], 0) + end - start
    print("segment", max(sizes.values(), default=0))
    rclpy.shutdown()
    """
)


@pytest.mark.parametrize(
    ("kind", "size", "segment_range"),
    [
        ("default", 5, (256 * 1024, 1024 * 1024)),
        # 1 MB: twice what FastDDS's default segment holds, a dense lidar scan or a camera image.
        ("large", 1024 * 1024, (16 * 1024 * 1024, 20 * 1024 * 1024)),
    ],
)
def test_the_profile_parses_and_a_message_goes_through(
    ros_env: dict[str, str], kind: str, size: int, segment_range: tuple[int, int]
) -> None:
    from coral.sdk import dds

    env = {k: v for k, v in ros_env.items() if not k.endswith("_DEFAULT_PROFILES_FILE")}
    env.pop("FASTDDS_BUILTIN_TRANSPORTS", None)
    done = subprocess.run(
        [sys.executable, "-c", PROCESS, kind, str(size)],
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    assert "XMLPARSER" not in done.stderr, done.stderr
    profile = dds.LARGE_DATA_PROFILE if kind == "large" else dds.PROFILE
    assert f"profile {profile}" in done.stdout
    assert "received True" in done.stdout, done.stdout + done.stderr
    segment = int(done.stdout.split("segment ")[1].split()[0])
    assert segment_range[0] <= segment < segment_range[1], done.stdout
