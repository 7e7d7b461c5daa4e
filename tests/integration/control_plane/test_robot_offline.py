"""A robot that drops off the network turns Ready=Unknown and keeps its tolerating Pod, as on a fleet.

kwok stops renewing the robot's lease; the node-lifecycle controller notices after its grace
period, taints the Node unreachable (NoExecute) and marks its pods not ready. A Pod with the
robot tolerations must stay bound and come back Ready when the robot returns.
"""

from __future__ import annotations

import pytest
from coral_testbed.cluster import Cluster
from coral_testbed.waiting import holds_for, wait_for
from kubernetes import client as k8s

from .manifests import robot_pod

pytestmark = [pytest.mark.cluster, pytest.mark.slow]

ROBOT = "r-wanderer"
NEIGHBOURS = ["r1", "r2", "r3"]


def _node(core: k8s.CoreV1Api) -> tuple[str | None, set[str]]:
    """(Ready status, NoExecute taint keys) of the robot."""
    node = core.read_node(ROBOT)
    ready = next((c.status for c in node.status.conditions or [] if c.type == "Ready"), None)
    return ready, {t.key for t in node.spec.taints or [] if t.effect == "NoExecute"}


def _pod_ready(core: k8s.CoreV1Api, namespace: str) -> str | None:
    pod = core.read_namespaced_pod("roamer", namespace)
    return next((c.status for c in pod.status.conditions or [] if c.type == "Ready"), None)


def test_offline_robot_is_unknown_and_keeps_its_pod_until_it_returns(
    cluster: Cluster, namespace: str
) -> None:
    cluster.add_robots([ROBOT, *NEIGHBOURS])
    core = k8s.CoreV1Api(cluster.api_client)
    cluster.kubectl("apply", "-n", namespace, "-f", "-", input=robot_pod("roamer", ROBOT))
    wait_for(lambda: _pod_ready(core, namespace) == "True", timeout=90, message="pod roamer to be Ready")

    try:
        cluster.set_robot_reachable(ROBOT, False)
        assert _node(core)[0] == "Unknown"
        assert cluster.kubectl("get", "node", ROBOT, "--no-headers").stdout.split()[1] == "NotReady"
        wait_for(
            lambda: "node.kubernetes.io/unreachable" in _node(core)[1],
            timeout=60,
            message=lambda: f"the unreachable NoExecute taint on {ROBOT} (node: {_node(core)})",
        )
        wait_for(
            lambda: _pod_ready(core, namespace) == "False",
            timeout=60,
            message="pod roamer to be marked not ready",
        )

        def bound_and_alive() -> bool:
            pod = core.read_namespaced_pod("roamer", namespace)
            return pod.metadata.deletion_timestamp is None and pod.spec.node_name == ROBOT

        holds_for(bound_and_alive, duration=10, message="pod roamer on the offline robot")
    finally:
        cluster.set_robot_reachable(ROBOT, True)

    wait_for(
        lambda: not _node(core)[1], timeout=60, message=lambda: f"taints to leave {ROBOT}: {_node(core)}"
    )
    wait_for(lambda: _pod_ready(core, namespace) == "True", timeout=90, message="pod roamer Ready again")
