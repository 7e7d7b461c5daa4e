"""Simulated robots: kwok-managed Nodes labelled `coral.dev/robot=<name>`.

Node manifests and readiness parsing are pure; the `apply_*`/`read_*` functions talk to the API
and are used by `client.Cluster` (tests, the demo, `coral dev-cluster local robots`). Not ready is an
annotation that kwok's stages (kwok-stages.yaml) turn into Ready=False; offline is the kwok label
switched off, so the robot's lease lapses and the node-lifecycle controller reports it Unknown.
"""

from __future__ import annotations

import datetime
import re
from importlib import resources
from typing import Any

from coral_core.names import LABEL_ROBOT as ROBOT_LABEL
from kubernetes import client as k8s
from kubernetes.client.exceptions import ApiException

from coral_testbed.cluster import components
from coral_testbed.waiting import wait_for

NOT_READY_ANNOTATION = "coral.dev/simulate-not-ready"

# A robot name is both a Node name and a label value: the intersection of the two syntaxes.
_NAME = re.compile(r"^[a-z0-9]([a-z0-9.-]{0,61}[a-z0-9])?$")


def kwok_stages() -> str:
    return resources.files("coral_testbed.cluster").joinpath("kwok-stages.yaml").read_text()


def validate_robot_name(name: str) -> str:
    if not _NAME.match(name):
        raise ValueError(
            f"robot name {name!r} is invalid: use 1-63 lowercase letters, digits, '-' or '.', "
            "starting and ending with a letter or digit"
        )
    return name


def build_robot_node(name: str, labels: dict[str, str] | None = None) -> dict[str, Any]:
    """The Node of a simulated robot; extra `labels` cannot override the robot or hostname label."""
    validate_robot_name(name)
    return {
        "apiVersion": "v1",
        "kind": "Node",
        "metadata": {
            "name": name,
            "labels": {
                "kubernetes.io/os": "linux",
                "kubernetes.io/arch": "amd64",
                "type": "kwok",
                **(labels or {}),
                ROBOT_LABEL: name,
                "kubernetes.io/hostname": name,
                components.KWOK_LABEL: components.KWOK_ONLINE,
            },
            "annotations": {"node.alpha.kubernetes.io/ttl": "0"},
        },
    }


def ready_status(node: Any) -> str | None:
    """ "True", "False" or "Unknown" from a Node's Ready condition (None before the first report)."""
    for condition in (node.status.conditions if node.status else None) or []:
        if condition.type == "Ready":
            return str(condition.status)
    return None


def apply_robots(api: k8s.ApiClient, names: list[str], labels: dict[str, str] | None = None) -> list[str]:
    """Creates the robots' Nodes, or merges the labels into existing ones (idempotent).

    Returns:
        the names that were created (the others existed already).
    """
    core = k8s.CoreV1Api(api)
    created = []
    for name in names:
        body = build_robot_node(name, labels)
        try:
            core.create_node(body)
            created.append(name)
        except ApiException as error:
            if error.status != 409:
                raise
            # An existing robot keeps its online/offline state; only the other labels are merged.
            labels = {k: v for k, v in body["metadata"]["labels"].items() if k != components.KWOK_LABEL}
            core.patch_node(name, {"metadata": {"labels": labels}})
    return created


def delete_robots(api: k8s.ApiClient, names: list[str]) -> None:
    core = k8s.CoreV1Api(api)
    for name in names:
        try:
            core.delete_node(name)
        except ApiException as error:
            if error.status != 404:
                raise


def _await_ready_status(core: k8s.CoreV1Api, name: str, wanted: str, timeout: float, hint: str = "") -> None:
    seen: list[str | None] = [None]

    def reports_wanted() -> bool:
        seen[0] = ready_status(core.read_node(name))
        return seen[0] == wanted

    wait_for(
        reports_wanted,
        timeout=timeout,
        interval=0.3,
        message=lambda: f"robot {name} to report Ready={wanted} (last seen Ready={seen[0]}){hint}",
    )


def apply_robot_ready(api: k8s.ApiClient, name: str, ready: bool) -> None:
    """Marks a robot Ready or NotReady through kwok and waits until its Ready condition says so."""
    core = k8s.CoreV1Api(api)
    value = None if ready else "true"
    core.patch_node(name, {"metadata": {"annotations": {NOT_READY_ANNOTATION: value}}})
    _await_ready_status(core, name, "True" if ready else "False", timeout=60, hint="; is kwok running?")
    if ready:
        apply_pods_ready_again(api, name)


def apply_robot_reachable(api: k8s.ApiClient, name: str, reachable: bool, timeout: float = 180) -> None:
    """Takes a robot off the network (kwok stops renewing its lease) or brings it back, and waits.

    Offline, the node-lifecycle controller marks the Node Ready=Unknown once its lease has gone
    unrenewed for the grace period, and taints it `node.kubernetes.io/unreachable`; back online,
    kwok resumes the lease and reports Ready=True, and the robot's pods are reported Ready again.
    """
    core = k8s.CoreV1Api(api)
    value = components.KWOK_ONLINE if reachable else components.KWOK_OFFLINE
    core.patch_node(name, {"metadata": {"labels": {components.KWOK_LABEL: value}}})
    _await_ready_status(core, name, "True" if reachable else "Unknown", timeout=timeout)
    if reachable:
        apply_pods_ready_again(api, name)


def apply_pods_ready_again(api: k8s.ApiClient, name: str) -> int:
    """Reports the running pods of a recovered robot Ready again, as its kubelet would; returns how many.

    The node-lifecycle controller marks a robot's pods not ready when the robot stops being Ready,
    and kwok only sets readiness when it first starts a pod, so recovery is reported here.
    """
    core = k8s.CoreV1Api(api)
    now = datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%dT%H:%M:%SZ")
    restored = 0
    for pod in core.list_pod_for_all_namespaces(field_selector=f"spec.nodeName={name}").items:
        if pod.metadata.deletion_timestamp is not None or pod.status.phase != "Running":
            continue
        if all(c.status == "True" for c in pod.status.conditions or [] if c.type == "Ready"):
            continue
        conditions = [
            {"type": kind, "status": "True", "lastTransitionTime": now}
            for kind in ("Ready", "ContainersReady")
        ]
        try:
            core.patch_namespaced_pod_status(
                pod.metadata.name, pod.metadata.namespace, {"status": {"conditions": conditions}}
            )
        except ApiException as error:
            # Deleted since the list (the operator replaces a returning robot's pods at once).
            if error.status != 404:
                raise
            continue
        restored += 1
    return restored


def wait_robots_ready(api: k8s.ApiClient, names: list[str], timeout: float = 60) -> None:
    core = k8s.CoreV1Api(api)
    pending = set(names)

    def all_ready() -> bool:
        for node in core.list_node(label_selector=ROBOT_LABEL).items:
            if ready_status(node) == "True":
                pending.discard(node.metadata.name)
        return not pending

    wait_for(
        all_ready,
        timeout=timeout,
        message=lambda: f"robots {sorted(pending)} to become Ready; is kwok running?",
    )
