"""Acceptance (d): a robot set NotReady reports Ready=False, and a Pod tolerating that is not evicted.

The taint-eviction controller's reaction is observed on a second Pod on the same robot that
tolerates not-ready for one second only: once it is evicted, the controller has acted, and the
tolerating Pod must still be there, bound and not terminating, for a further bounded window.
"""

from __future__ import annotations

import pytest
from coral_testbed.cluster import Cluster
from coral_testbed.waiting import holds_for, wait_for
from fixtures.tolerations import robot_down_tolerations
from kubernetes import client as k8s
from kubernetes.client.exceptions import ApiException

from .manifests import ROBOT_TOLERATIONS, robot_pod

pytestmark = [pytest.mark.cluster, pytest.mark.slow]

ROBOT = "r-flaky"
# Healthy neighbours keep the node-lifecycle controller out of its "zone disrupted" mode, in which
# it stops evicting altogether and the test would prove nothing.
NEIGHBOURS = ["r1", "r2", "r3"]
SHORT_TOLERATION = robot_down_tolerations(seconds=1)


def _pod(core: k8s.CoreV1Api, name: str, namespace: str) -> k8s.V1Pod | None:
    try:
        return core.read_namespaced_pod(name, namespace)
    except ApiException as error:
        if error.status == 404:
            return None
        raise


def _ready(core: k8s.CoreV1Api, node: str) -> str | None:
    conditions = core.read_node(node).status.conditions or []
    return next((c.status for c in conditions if c.type == "Ready"), None)


def _no_execute_taints(core: k8s.CoreV1Api, node: str) -> set[str]:
    return {t.key for t in core.read_node(node).spec.taints or [] if t.effect == "NoExecute"}


def test_not_ready_robot_keeps_its_tolerating_pod(cluster: Cluster, namespace: str) -> None:
    cluster.add_robots([ROBOT, *NEIGHBOURS])
    core = k8s.CoreV1Api(cluster.api_client)
    cluster.kubectl(
        "apply", "-n", namespace, "-f", "-", input=robot_pod("steadfast", ROBOT, ROBOT_TOLERATIONS)
    )
    cluster.kubectl("apply", "-n", namespace, "-f", "-", input=robot_pod("fickle", ROBOT, SHORT_TOLERATION))
    for name in ("steadfast", "fickle"):
        wait_for(
            lambda name=name: (_pod(core, name, namespace) or k8s.V1Pod()).status.phase == "Running",
            timeout=90,
            message=f"pod {name} to be Running",
        )

    try:
        cluster.set_robot_ready(ROBOT, False)
        assert _ready(core, ROBOT) == "False"
        node_line = cluster.kubectl("get", "node", ROBOT, "--no-headers").stdout.split()
        assert node_line[1] == "NotReady"

        wait_for(
            lambda: "node.kubernetes.io/not-ready" in _no_execute_taints(core, ROBOT),
            timeout=60,
            message=lambda: f"NoExecute not-ready taint on {ROBOT} (has {_no_execute_taints(core, ROBOT)})",
        )
        wait_for(
            lambda: _pod(core, "fickle", namespace) is None,
            timeout=90,
            message="the briefly tolerating pod fickle to be evicted",
        )

        def steadfast_stays() -> bool:
            pod = _pod(core, "steadfast", namespace)
            return pod is not None and pod.metadata.deletion_timestamp is None and pod.spec.node_name == ROBOT

        holds_for(steadfast_stays, duration=15, message="pod steadfast on the NotReady robot")
        assert _ready(core, ROBOT) == "False", (
            "the robot should still report Ready=False (kwok renews its lease)"
        )
    finally:
        cluster.set_robot_ready(ROBOT, True)

    wait_for(
        lambda: not _no_execute_taints(core, ROBOT),
        timeout=60,
        message=lambda: f"NoExecute taints to leave {ROBOT} (has {_no_execute_taints(core, ROBOT)})",
    )
    pod = _pod(core, "steadfast", namespace)
    assert pod is not None and pod.status.phase == "Running"
    assert [c.status for c in pod.status.conditions if c.type == "Ready"] == ["True"]
