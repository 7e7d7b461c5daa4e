"""A pod's life on a kind robot as the operator reads it: exit codes, restarts, deletion, config.

The operator judges components by what the kubelet reports: an executor's exit code and restart
count, a container that cannot start because its ConfigMap is missing. These tests apply plain
pods on a robot of the kind cluster (its kubelet and containerd) and check the pod status, the
robot's files and its containerd (through the CRI), read inside the robot's node.
"""

from __future__ import annotations

from typing import Any

import pytest
import yaml
from coral_testbed.kind import faults
from coral_testbed.waiting import wait_for
from kubernetes import client as k8s

from .fleet import KindCluster, crictl, on_robot
from .pods import robot_pod, wait_pod

pytestmark = [pytest.mark.slow, pytest.mark.timeout(1800)]

ROBOT = "relay-worker"


def _pod(name: str, script: str, restart: str, host_path: str | None = None) -> dict[str, Any]:
    manifest = yaml.safe_load(robot_pod(name, ROBOT, script, host_path=host_path))
    manifest["spec"]["restartPolicy"] = restart
    return manifest


def _ended(core: k8s.CoreV1Api, namespace: str, name: str) -> k8s.V1Pod:
    return wait_for(
        lambda: (
            (p := core.read_namespaced_pod(name, namespace)).status.phase in ("Succeeded", "Failed") and p
        ),
        timeout=90,
        interval=0.5,
        message=f"pod {name} to end",
    )


def test_failing_container_makes_the_pod_failed_with_its_exit_code(
    kind_cluster: KindCluster, kind_namespace: str, robot_test_image: str
) -> None:
    core = k8s.CoreV1Api(kind_cluster.cluster.api_client)
    core.create_namespaced_pod(kind_namespace, _pod("failing", "exit 3", "Never"))

    pod = _ended(core, kind_namespace, "failing")
    assert pod.status.phase == "Failed"
    terminated = pod.status.container_statuses[0].state.terminated
    assert terminated.exit_code == 3 and terminated.reason == "Error"


def test_on_failure_pod_is_restarted_until_it_succeeds(
    kind_cluster: KindCluster, kind_namespace: str, robot_test_image: str
) -> None:
    core = k8s.CoreV1Api(kind_cluster.cluster.api_client)
    folder = f"/var/lib/coral/test-{kind_namespace}"
    script = 'n=$(ls /shared | wc -l); touch /shared/attempt-$n; [ "$n" -ge 1 ] || exit 4'
    core.create_namespaced_pod(kind_namespace, _pod("flaky", script, "OnFailure", host_path=folder))

    pod = _ended(core, kind_namespace, "flaky")
    assert pod.status.phase == "Succeeded"
    status = pod.status.container_statuses[0]
    # One failed run (exit 4, its file attempt-0), then the run that succeeded.
    assert status.restart_count == 1 and status.state.terminated.exit_code == 0
    attempts = on_robot(kind_cluster.running, ROBOT, "ls", "-1", folder).split()
    assert sorted(attempts) == ["attempt-0", "attempt-1"]


def test_deleting_a_long_running_pod_stops_its_container(
    kind_cluster: KindCluster, kind_namespace: str, robot_test_image: str
) -> None:
    core = k8s.CoreV1Api(kind_cluster.cluster.api_client)
    core.create_namespaced_pod(kind_namespace, _pod("forever", "exec sleep 3600", "Always"))
    wait_pod(core, kind_namespace, "forever")

    def containers() -> list[str]:
        label = f"io.kubernetes.pod.namespace={kind_namespace}"
        return crictl(kind_cluster.running, ROBOT, "ps", "-q", "--label", label).split()

    assert len(containers()) == 1
    core.delete_namespaced_pod("forever", kind_namespace, grace_period_seconds=1)
    wait_for(lambda: not containers(), timeout=60, message="the deleted pod's container to stop")

    def gone() -> bool:
        return not core.list_namespaced_pod(kind_namespace, field_selector="metadata.name=forever").items

    wait_for(gone, timeout=60, message="the pod object to be removed")


def test_env_from_configmap_and_downward_api_reach_the_container(
    kind_cluster: KindCluster, kind_namespace: str, robot_test_image: str
) -> None:
    cluster = kind_cluster.cluster
    core = k8s.CoreV1Api(cluster.api_client)
    core.create_namespaced_config_map(
        kind_namespace,
        {"metadata": {"name": "settings"}, "data": {"speed": "0.5", "mode": "survey", "tree": "<root/>"}},
    )
    manifest = _pod(
        "envdump",
        'echo "$SPEED|$POD_NAME|$NODE_NAME|$GREETING|$CFG_mode|$(cat /config/tree)"',
        "Never",
    )
    container = manifest["spec"]["containers"][0]
    container["env"] = [
        {"name": "SPEED", "valueFrom": {"configMapKeyRef": {"name": "settings", "key": "speed"}}},
        {"name": "POD_NAME", "valueFrom": {"fieldRef": {"fieldPath": "metadata.name"}}},
        {"name": "NODE_NAME", "valueFrom": {"fieldRef": {"fieldPath": "spec.nodeName"}}},
        {"name": "GREETING", "value": "hello $(NODE_NAME)"},
    ]
    container["envFrom"] = [{"prefix": "CFG_", "configMapRef": {"name": "settings"}}]
    container["volumeMounts"] = [{"name": "config", "mountPath": "/config", "readOnly": True}]
    manifest["spec"]["volumes"] = [{"name": "config", "configMap": {"name": "settings"}}]
    core.create_namespaced_pod(kind_namespace, manifest)

    pod = _ended(core, kind_namespace, "envdump")
    assert pod.status.phase == "Succeeded"
    # The robot's Node (a kind worker) is named by kind, not after the robot.
    node = faults.node_of(kind_cluster.running, ROBOT)
    assert pod.spec.node_name == node
    logs = cluster.kubectl("logs", "-n", kind_namespace, "envdump").stdout.strip()
    assert logs == f"0.5|envdump|{node}|hello {node}|survey|<root/>"


def test_missing_configmap_is_reported_as_a_container_config_error(
    kind_cluster: KindCluster, kind_namespace: str, robot_test_image: str
) -> None:
    core = k8s.CoreV1Api(kind_cluster.cluster.api_client)
    manifest = _pod("misconfigured", "true", "Never")
    manifest["spec"]["containers"][0]["env"] = [
        {"name": "X", "valueFrom": {"configMapKeyRef": {"name": "absent", "key": "x"}}}
    ]
    core.create_namespaced_pod(kind_namespace, manifest)

    def waiting_reason() -> Any:
        statuses = core.read_namespaced_pod("misconfigured", kind_namespace).status.container_statuses or []
        waiting = statuses[0].state.waiting if statuses else None
        return waiting if waiting and waiting.reason == "CreateContainerConfigError" else None

    waiting = wait_for(waiting_reason, timeout=60, interval=0.5, message="CreateContainerConfigError")
    assert "absent" in waiting.message
    assert core.read_namespaced_pod("misconfigured", kind_namespace).status.phase == "Pending"
