"""The Node side of a runner-managed robot: registration, adoption from kwok, heartbeats.

Called by `runner.robots`. kwok manages the Nodes labelled `coral.dev/simulation=online` (a
server-side label selector, see `coral_testbed.cluster.components`). A runner-managed robot is a
Node labelled `coral.dev/robot=<name>` and `coral.dev/simulation=robot-runner`, annotated
`coral.dev/robot-runner=<runner id>`: kwok leaves it and its pods alone, and the runner posts its
Ready condition and renews its Lease, as a kubelet does. Adopting a kwok robot relabels it (kwok
lets go of a Node that leaves its selector); a Node that kwok manages through the older
`kwok.x-k8s.io/node` annotation, which kwok caches, is re-created instead.
"""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Any

from coral_operator.api.names import LABEL_ROBOT as ROBOT_LABEL
from kubernetes import client as k8s
from kubernetes.client.exceptions import ApiException

from coral_testbed.cluster import components
from coral_testbed.waiting import wait_for

RUNNER_ANNOTATION = "coral.dev/robot-runner"
KWOK_ANNOTATION = "kwok.x-k8s.io/node"
SIMULATION_LABEL = components.KWOK_LABEL
KWOK_MANAGED = components.KWOK_ONLINE
RUNNER_MANAGED = "robot-runner"
LEASE_NAMESPACE = "kube-node-lease"
LEASE_SECONDS = 40
MERGE_PATCH = "application/merge-patch+json"


class AdoptionRefused(RuntimeError):
    """The robot's Node belongs to kwok (or another runner) and adoption was not allowed."""


def micro_time(moment: datetime) -> str:
    return moment.astimezone(UTC).strftime("%Y-%m-%dT%H:%M:%S.%fZ")


def build_node(name: str, labels: dict[str, str], runner_id: str) -> dict[str, Any]:
    return {
        "apiVersion": "v1",
        "kind": "Node",
        "metadata": {
            "name": name,
            "labels": {
                "kubernetes.io/os": "linux",
                "kubernetes.io/arch": "amd64",
                **labels,
                "type": "coral-robot-runner",
                SIMULATION_LABEL: RUNNER_MANAGED,
                ROBOT_LABEL: name,
                "kubernetes.io/hostname": name,
            },
            "annotations": {RUNNER_ANNOTATION: runner_id, "node.alpha.kubernetes.io/ttl": "0"},
        },
    }


def ensure_node(core: k8s.CoreV1Api, name: str, runner_id: str, adopt: bool) -> bool:
    """Makes `name` a Node this runner manages; returns True if the Node was created or re-created.

    A Node that exists without kwok's marks (made by an earlier runner, or by hand) is taken as is.

    Raises:
        AdoptionRefused: the Node is kwok's and `adopt` is False.
    """
    try:
        node = core.read_node(name)
    except ApiException as error:
        if error.status != 404:
            raise
        core.create_node(build_node(name, {}, runner_id))
        return True
    annotations = node.metadata.annotations or {}
    labels = node.metadata.labels or {}
    # Any other value (kwok's "offline" too) marks a kwok robot.
    by_label = labels.get(SIMULATION_LABEL, RUNNER_MANAGED) != RUNNER_MANAGED
    by_annotation = KWOK_ANNOTATION in annotations
    if (by_label or by_annotation) and not adopt:
        raise AdoptionRefused(
            f"robot {name} is simulated by kwok (Node label {SIMULATION_LABEL} or "
            f"annotation {KWOK_ANNOTATION}); run with adopt=True (--adopt) to take it over"
        )
    if not by_annotation:
        patch = {
            "metadata": {
                "labels": {SIMULATION_LABEL: RUNNER_MANAGED, ROBOT_LABEL: labels.get(ROBOT_LABEL, name)},
                "annotations": {RUNNER_ANNOTATION: runner_id},
            }
        }
        core.patch_node(name, patch)
        return False
    kept = {k: v for k, v in labels.items() if k not in ("type", SIMULATION_LABEL)}
    core.delete_node(name)

    def gone() -> bool:
        try:
            core.read_node(name)
        except ApiException as error:
            if error.status == 404:
                return True
            raise
        return False

    wait_for(gone, timeout=30, message=f"Node {name} to be deleted for adoption")
    core.create_node(build_node(name, kept, runner_id))
    return True


def build_node_status(ready: bool, reason: str, message: str, address: str, now: datetime) -> dict[str, Any]:
    stamp = now.astimezone(UTC).strftime("%Y-%m-%dT%H:%M:%SZ")
    pressure = [
        ("MemoryPressure", "KubeletHasSufficientMemory"),
        ("DiskPressure", "KubeletHasNoDiskPressure"),
        ("PIDPressure", "KubeletHasSufficientPID"),
    ]
    conditions = [
        {
            "type": kind,
            "status": "False",
            "reason": why,
            "message": why,
            "lastHeartbeatTime": stamp,
            "lastTransitionTime": stamp,
        }
        for kind, why in pressure
    ]
    conditions.append(
        {
            "type": "Ready",
            "status": "True" if ready else "False",
            "reason": reason,
            "message": message,
            "lastHeartbeatTime": stamp,
            "lastTransitionTime": stamp,
        }
    )
    resources = {"cpu": "8", "memory": "16Gi", "pods": "110"}
    return {
        "status": {
            "conditions": conditions,
            "addresses": [{"type": "InternalIP", "address": address}],
            "capacity": resources,
            "allocatable": resources,
            "nodeInfo": {
                "architecture": "amd64",
                "operatingSystem": "linux",
                "kubeletVersion": "coral-robot-runner",
                "containerRuntimeVersion": "coral-robot-runner://0.1",
                "kernelVersion": "",
                "kubeProxyVersion": "",
                "osImage": "",
                "machineID": "",
                "systemUUID": "",
                "bootID": "",
            },
        }
    }


def report_node(core: k8s.CoreV1Api, name: str, status: dict[str, Any]) -> None:
    # lastTransitionTime must survive heartbeats, so keep the previous one when the status is the same.
    node = core.read_node(name)
    previous = {c.type: c for c in (node.status.conditions or [])} if node.status else {}
    for condition in status["status"]["conditions"]:
        old = previous.get(condition["type"])
        if old is not None and old.status == condition["status"] and old.last_transition_time is not None:
            condition["lastTransitionTime"] = old.last_transition_time.strftime("%Y-%m-%dT%H:%M:%SZ")
    core.patch_node_status(name, status, _content_type=MERGE_PATCH)


def renew_lease(coordination: k8s.CoordinationV1Api, node_uid: str, name: str, now: datetime) -> None:
    body = {
        "metadata": {
            "name": name,
            "namespace": LEASE_NAMESPACE,
            "ownerReferences": [{"apiVersion": "v1", "kind": "Node", "name": name, "uid": node_uid}],
        },
        "spec": {"holderIdentity": name, "leaseDurationSeconds": LEASE_SECONDS, "renewTime": micro_time(now)},
    }
    try:
        coordination.patch_namespaced_lease(name, LEASE_NAMESPACE, {"spec": body["spec"]})
    except ApiException as error:
        if error.status != 404:
            raise
        coordination.create_namespaced_lease(LEASE_NAMESPACE, body)
