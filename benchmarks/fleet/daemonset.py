"""The baseline: a DaemonSet running the same three containers on every robot.

Same images, host network and IPC, and DaemonSet tolerations as the Coral pods; one pod with three
containers per robot, as Kubernetes would run the mission without Coral. `run_daemonset` measures
the time until every pod is Ready and the time of a rolling update at the same `maxUnavailable`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

from coral_testbed.waiting import wait_for
from kubernetes import client as k8s

from fleet.robots import FLEET_LABEL

NAME = "mission"
COMPONENTS = (
    ("lidar-driver", "coral/lidar-driver:0.1.0"),
    ("slam", "coral/slam-skillset:0.1.0"),
    ("executor", "coral/executor:0.1.0"),
)
TOLERATIONS = [
    {"key": "node.kubernetes.io/unreachable", "operator": "Exists", "effect": "NoExecute"},
    {"key": "node.kubernetes.io/not-ready", "operator": "Exists", "effect": "NoExecute"},
    {"key": "node.kubernetes.io/unschedulable", "operator": "Exists", "effect": "NoSchedule"},
]


def build_daemonset(namespace: str, revision: str, max_unavailable: str) -> dict[str, Any]:
    labels = {"app": NAME}
    containers = [
        {"name": name, "image": image, "env": [{"name": "MISSION_REVISION", "value": revision}]}
        for name, image in COMPONENTS
    ]
    return {
        "apiVersion": "apps/v1",
        "kind": "DaemonSet",
        "metadata": {"name": NAME, "namespace": namespace},
        "spec": {
            "selector": {"matchLabels": labels},
            "updateStrategy": {"type": "RollingUpdate", "rollingUpdate": {"maxUnavailable": max_unavailable}},
            "template": {
                "metadata": {"labels": labels},
                "spec": {
                    "nodeSelector": {FLEET_LABEL: "bench"},
                    "tolerations": TOLERATIONS,
                    "hostNetwork": True,
                    "hostIPC": True,
                    "dnsPolicy": "ClusterFirstWithHostNet",
                    "enableServiceLinks": False,
                    "automountServiceAccountToken": False,
                    "containers": containers,
                },
            },
        },
    }


@dataclass
class DaemonSetResult:
    ready_seconds: float
    update_seconds: float


def _status(apps: k8s.AppsV1Api, namespace: str) -> Any:
    return apps.read_namespaced_daemon_set_status(NAME, namespace)


def _settled(apps: k8s.AppsV1Api, namespace: str, count: int) -> bool:
    ds = _status(apps, namespace)
    s = ds.status
    return bool(
        s
        and (s.observed_generation or 0) >= ds.metadata.generation
        and s.desired_number_scheduled == count
        and (s.updated_number_scheduled or 0) == count
        and (s.number_ready or 0) == count
        and (s.number_available or 0) == count
    )


def run_daemonset(api: k8s.ApiClient, namespace: str, count: int, timeout: float) -> DaemonSetResult:
    apps = k8s.AppsV1Api(api)
    began = time.monotonic()
    apps.create_namespaced_daemon_set(namespace, build_daemonset(namespace, "1", "10%"))
    wait_for(
        lambda: _settled(apps, namespace, count),
        timeout=timeout,
        interval=0.5,
        message=f"DaemonSet on {count} robots to become Ready",
    )
    ready = time.monotonic() - began
    began = time.monotonic()
    patch = build_daemonset(namespace, "2", "10%")
    apps.patch_namespaced_daemon_set(NAME, namespace, {"spec": patch["spec"]})
    wait_for(
        lambda: _settled(apps, namespace, count),
        timeout=timeout,
        interval=0.5,
        message=f"DaemonSet rolling update over {count} robots",
    )
    return DaemonSetResult(ready_seconds=ready, update_seconds=time.monotonic() - began)


def delete_daemonset(api: k8s.ApiClient, namespace: str, timeout: float) -> None:
    """Deletes the DaemonSet and waits until its pods are gone, so the next run starts clean."""
    apps, core = k8s.AppsV1Api(api), k8s.CoreV1Api(api)
    apps.delete_namespaced_daemon_set(NAME, namespace, propagation_policy="Background")
    wait_for(
        lambda: not core.list_namespaced_pod(namespace, limit=1).items,
        timeout=timeout,
        interval=2.0,
        message="the DaemonSet's pods to be deleted",
    )
