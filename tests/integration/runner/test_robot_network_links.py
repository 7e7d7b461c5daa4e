"""Robots live on separate network namespaces: ROS 2 traffic between them crosses a link that can be cut,
and the Kubernetes API is reachable from inside a robot exactly while its link is up."""

from __future__ import annotations

import time
from pathlib import Path

import pytest
from coral_testbed.cluster import Cluster
from coral_testbed.waiting import holds_for, wait_for
from kubernetes import client as k8s

from .conftest import StartRunner
from .podmanifests import python_pod, wait_phase

pytestmark = [pytest.mark.cluster, pytest.mark.slow]

PUBLISHER = """
import rclpy
from std_msgs.msg import String
rclpy.init()
node = rclpy.create_node("talker")
publisher = node.create_publisher(String, "chatter", 10)
count = 0
def send():
    global count
    count += 1
    publisher.publish(String(data=str(count)))
node.create_timer(0.1, send)
rclpy.spin(node)
"""

SUBSCRIBER = """
import rclpy
from std_msgs.msg import String
rclpy.init()
node = rclpy.create_node("listener")
out = open("/data/received", "a", buffering=1)
node.create_subscription(String, "chatter", lambda message: out.write(message.data + "\\n"), 10)
rclpy.spin(node)
"""

API_PROBE = """
import time
from kubernetes import client, config
while True:
    try:
        config.load_kube_config()
        with client.ApiClient() as api:
            version = client.VersionApi(api).get_code(_request_timeout=2)
        line = "ok " + version.git_version
    except Exception as error:
        line = "fail " + type(error).__name__
    open("/data/api", "a").write(line + "\\n")
    time.sleep(0.3)
"""


def _lines(path: Path) -> list[str]:
    return path.read_text().splitlines() if path.exists() else []


def _node_ready(core: k8s.CoreV1Api, name: str) -> str | None:
    conditions = core.read_node(name).status.conditions or []
    return next((c.status for c in conditions if c.type == "Ready"), None)


def _ros_env(ros_env: dict[str, str]) -> list[dict[str, str]]:
    return [
        {"name": "ROS_DOMAIN_ID", "value": ros_env["ROS_DOMAIN_ID"]},
        {"name": "ROS_AUTOMATIC_DISCOVERY_RANGE", "value": "SUBNET"},
        {"name": "RMW_IMPLEMENTATION", "value": "rmw_fastrtps_cpp"},
    ]


@pytest.mark.ros
def test_ros_traffic_between_two_robots_stops_when_the_link_is_cut_and_resumes_when_restored(
    cluster: Cluster,
    namespace: str,
    start_runner: StartRunner,
    robot_names,
    ros_env: dict[str, str],
) -> None:
    r1, r2 = robot_names("r1", "r2")
    runner = start_runner([r1, r2])
    if not runner.isolated:
        pytest.skip("network namespaces are not available here (needs root and iproute2)")
    core = k8s.CoreV1Api(cluster.api_client)
    env = _ros_env(ros_env)
    for name, robot, code in (("listener", r2, SUBSCRIBER), ("talker", r1, PUBLISHER)):
        manifest = python_pod(name, robot, code, restart="Always", env=env)
        manifest["spec"]["hostNetwork"] = True
        core.create_namespaced_pod(namespace, manifest)
    wait_phase(core, "talker", namespace, ("Running",))
    received = runner.host_path(r2, "/srv/data/received")

    wait_for(lambda: len(_lines(received)) >= 5, timeout=60, message="r2 to hear r1 over the bridge")

    runner.cut_link(r1)
    # Once nothing arrived for 2 s, the cut has taken effect; then nothing more may arrive.
    wait_for(lambda: time.time() - received.stat().st_mtime > 2.0, timeout=30, message="traffic to stop")
    at_cut = len(_lines(received))
    holds_for(lambda: len(_lines(received)) == at_cut, duration=3.0, message="no traffic while cut")

    last_before = int(_lines(received)[-1])
    runner.restore_link(r1)
    wait_for(
        lambda: len(_lines(received)) >= at_cut + 5,
        timeout=60,
        message="traffic from r1 to resume after the link is restored",
    )
    assert int(_lines(received)[-1]) > last_before


def test_api_is_reachable_inside_a_robot_only_while_its_link_is_up_and_a_cut_robot_becomes_unknown(
    cluster: Cluster, namespace: str, start_runner: StartRunner, robot_names
) -> None:
    (r1,) = robot_names("r1")
    runner = start_runner([r1])
    core = k8s.CoreV1Api(cluster.api_client)
    coordination = k8s.CoordinationV1Api(cluster.api_client)
    core.create_namespaced_pod(namespace, python_pod("apiprobe", r1, API_PROBE, restart="Always"))
    results = runner.host_path(r1, "/srv/data/api")

    wait_for(lambda: any(x.startswith("ok ") for x in _lines(results)), timeout=60, message="API from r1")

    runner.cut_link(r1)
    seen = len(_lines(results))
    wait_for(
        lambda: any(x.startswith("fail") for x in _lines(results)[seen:]),
        timeout=30,
        message="API calls from r1 to fail while its link is cut",
    )
    # The robot's kubelet is cut off too: its Node lease is no longer renewed.
    renewed = coordination.read_namespaced_lease(r1, "kube-node-lease").spec.renew_time
    holds_for(
        lambda: coordination.read_namespaced_lease(r1, "kube-node-lease").spec.renew_time == renewed,
        duration=12.0,
        message="lease of a cut-off robot unchanged",
    )

    # Without heartbeats the control plane declares the robot unreachable (node monitor grace period).
    wait_for(
        lambda: _node_ready(core, r1) == "Unknown",
        timeout=120,
        interval=1.0,
        message=lambda: f"Node {r1} Ready=Unknown while cut (now {_node_ready(core, r1)})",
    )

    runner.restore_link(r1)
    seen = len(_lines(results))
    wait_for(
        lambda: any(x.startswith("ok ") for x in _lines(results)[seen:]),
        timeout=60,
        message="API from r1 again after restore",
    )
    wait_for(lambda: _node_ready(core, r1) == "True", timeout=15, message="Node Ready again after restore")
    assert coordination.read_namespaced_lease(r1, "kube-node-lease").spec.renew_time != renewed


def test_without_namespaces_robots_share_the_host_network_and_a_cut_still_stops_api_traffic(
    cluster: Cluster, namespace: str, start_runner: StartRunner, robot_names
) -> None:
    """The fallback for machines where namespaces cannot be made (not root): forced here with
    isolate=False, so it is tested on every machine."""
    (r1,) = robot_names("r1")
    runner = start_runner([r1], isolate=False)
    assert not runner.isolated
    assert runner.address(r1) == "127.0.0.1"
    core = k8s.CoreV1Api(cluster.api_client)
    core.create_namespaced_pod(namespace, python_pod("apiprobe", r1, API_PROBE, restart="Always"))
    results = runner.host_path(r1, "/srv/data/api")
    wait_for(lambda: any(x.startswith("ok ") for x in _lines(results)), timeout=60, message="API from r1")

    runner.cut_link(r1)
    seen = len(_lines(results))
    wait_for(
        lambda: any(x.startswith("fail") for x in _lines(results)[seen:]),
        timeout=30,
        message="API calls from r1 to fail while its link is cut",
    )
    runner.restore_link(r1)
    seen = len(_lines(results))
    wait_for(
        lambda: any(x.startswith("ok ") for x in _lines(results)[seen:]),
        timeout=60,
        message="API from r1 again after restore",
    )
