"""A real robot whose kubelet stops mid-mission, and comes back.

The Node turns NotReady (Ready=Unknown) once the controller manager's grace period passes; the
mission's pods stay bound to the robot (the operator neither deletes nor replaces them) and keep
running in its containerd. The robot's CoralInstance says `RobotReachable=False`, with the robot's
last-seen time taken from the Node's Lease (`kube-node-lease`), the heartbeat the kubelet renews
every ten seconds, in `status.robot.lastSeen` and in the condition's message. A restarted kubelet
brings the robot back: `RobotReachable=True`, the same pods, nothing restarted.
"""

from __future__ import annotations

from typing import Any

from coral_testbed.cluster import Cluster, realrobots, robots
from coral_testbed.waiting import wait_for
from fixtures.operator import HelmOperator
from kubernetes import client as k8s

from . import realsystems as rs
from .conftest import real_robot_marks

pytestmark = real_robot_marks(timeout_s=420)

SYSTEM = "patrol"
TREE = rs.LONG_WAIT_TREE


def _pods(core: k8s.CoreV1Api, namespace: str) -> dict[str, Any]:
    return {p.metadata.labels["coral.dev/component"]: p for p in rs.pods(core, namespace, SYSTEM)}


def test_stopped_kubelet_makes_the_robot_unreachable_with_its_lease_time_and_keeps_its_pods(
    cluster: Cluster,
    namespace: str,
    helm_operator: HelmOperator,
    real_robots: realrobots.RealRobots,
    real_robot: str,
    ros_env: dict[str, str],
) -> None:
    core = k8s.CoreV1Api(cluster.api_client)
    custom = k8s.CustomObjectsApi(cluster.api_client)
    leases = k8s.CoordinationV1Api(cluster.api_client)
    rs.create(custom, namespace, rs.system(SYSTEM, real_robot, int(ros_env["ROS_DOMAIN_ID"]), TREE))

    def current() -> dict:
        return rs.instance(custom, namespace, SYSTEM)

    wait_for(
        lambda: "WaitForCount" in rs.tree(current()).get("activePath", ""),
        timeout=240,
        message=lambda: f"the mission to run: {current()}\n{helm_operator.logs()[-2000:]}",
    )
    assert rs.condition(current(), "RobotReachable")["status"] == "True"
    before = _pods(core, namespace)
    assert set(before) == {rs.SKILLSET, "executor"}

    real_robots.stop(real_robot)
    wait_for(
        lambda: robots.ready_status(core.read_node(real_robot)) == "Unknown",
        timeout=120,
        message=f"{real_robot} to turn NotReady",
    )
    unreachable = wait_for(
        lambda: (i := current()) and rs.condition(i, "RobotReachable").get("status") == "False" and i,
        timeout=60,
        message=lambda: f"RobotReachable=False: {current()}",
    )
    # The kubelet is down, so its Lease no longer moves: its last renewal is when the robot was
    # last heard from.
    renewed = leases.read_namespaced_lease(real_robot, "kube-node-lease").spec.renew_time
    last_seen = renewed.strftime("%Y-%m-%dT%H:%M:%SZ")
    assert unreachable["status"]["robot"]["lastSeen"] == last_seen, unreachable["status"]["robot"]
    condition = rs.condition(unreachable, "RobotReachable")
    assert condition["reason"] == "NodeUnreachable", condition
    assert f"last seen {last_seen}" in condition["message"], condition

    during = _pods(core, namespace)
    for component, pod in during.items():
        assert pod.metadata.uid == before[component].metadata.uid, component
        assert pod.spec.node_name == real_robot and pod.metadata.deletion_timestamp is None, component
    # The containers never stopped: the robot's runtime still runs them while its kubelet is down.
    running = set(real_robots.cri(real_robot, "ps", "-q").stdout.split())
    for component, pod in before.items():
        assert rs.container_id(pod.status.container_statuses[0]) in running, component

    real_robots.start(real_robot)
    back = wait_for(
        lambda: (i := current()) and rs.condition(i, "RobotReachable").get("status") == "True" and i,
        timeout=90,
        message=lambda: f"RobotReachable=True again: {current()}",
    )
    assert "lastSeen" not in back["status"]["robot"], back["status"]["robot"]
    assert rs.tree(back)["rootStatus"] == "RUNNING", rs.tree(back)
    after = _pods(core, namespace)
    for component, pod in after.items():
        assert pod.metadata.uid == before[component].metadata.uid, component
        assert pod.status.container_statuses[0].restart_count == 0, component
    rs.delete(custom, namespace, SYSTEM)
