"""The baselines: DaemonSets running the same three components on every robot.

Same images, host network and IPC, and DaemonSet tolerations as the Coral pods. Two shapes, as
Kubernetes would run the mission without Coral:

- the floor, one DaemonSet whose pod holds the three containers (one pod per robot);
- the same shape as Coral's default layout, three DaemonSets, one per component (three pods per
  robot).

`run_daemonsets` measures the time until every pod of the given DaemonSets is Ready and the time
of a rolling update at the same `maxUnavailable` after one environment variable changes.
"""

from __future__ import annotations

import time
from collections.abc import Callable
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


def build_daemonset(
    namespace: str,
    revision: str,
    max_unavailable: str,
    name: str = NAME,
    components: tuple[tuple[str, str], ...] = COMPONENTS,
) -> dict[str, Any]:
    labels = {"app": name}
    containers = [
        {"name": component, "image": image, "env": [{"name": "MISSION_REVISION", "value": revision}]}
        for component, image in components
    ]
    return {
        "apiVersion": "apps/v1",
        "kind": "DaemonSet",
        "metadata": {"name": name, "namespace": namespace},
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


def single(namespace: str, revision: str, max_unavailable: str) -> list[dict[str, Any]]:
    """The floor: one DaemonSet, one pod with the three containers per robot."""
    return [build_daemonset(namespace, revision, max_unavailable)]


def per_component(namespace: str, revision: str, max_unavailable: str) -> list[dict[str, Any]]:
    """Coral's shape: one DaemonSet per component, three pods per robot."""
    return [
        build_daemonset(namespace, revision, max_unavailable, name=name, components=((name, image),))
        for name, image in COMPONENTS
    ]


@dataclass
class DaemonSetResult:
    ready_seconds: float
    update_seconds: float


def _settled(apps: k8s.AppsV1Api, namespace: str, names: list[str], count: int) -> bool:
    for name in names:
        ds = apps.read_namespaced_daemon_set_status(name, namespace)
        s = ds.status
        if not (
            s
            and (s.observed_generation or 0) >= ds.metadata.generation
            and s.desired_number_scheduled == count
            and (s.updated_number_scheduled or 0) == count
            and (s.number_ready or 0) == count
            and (s.number_available or 0) == count
        ):
            return False
    return True


def run_daemonsets(
    api: k8s.ApiClient, namespace: str, count: int, timeout: float, build: Callable[..., list[dict[str, Any]]]
) -> DaemonSetResult:
    """Create the DaemonSets `build` gives, wait until all are Ready, then roll an update through all."""
    apps = k8s.AppsV1Api(api)
    first = build(namespace, "1", "10%")
    names = [manifest["metadata"]["name"] for manifest in first]
    began = time.monotonic()
    for manifest in first:
        apps.create_namespaced_daemon_set(namespace, manifest)
    wait_for(
        lambda: _settled(apps, namespace, names, count),
        timeout=timeout,
        interval=0.5,
        message=f"DaemonSets {names} on {count} robots to become Ready",
    )
    ready = time.monotonic() - began
    began = time.monotonic()
    for manifest in build(namespace, "2", "10%"):
        apps.patch_namespaced_daemon_set(manifest["metadata"]["name"], namespace, {"spec": manifest["spec"]})
    wait_for(
        lambda: _settled(apps, namespace, names, count),
        timeout=timeout,
        interval=0.5,
        message=f"DaemonSets {names}: rolling update over {count} robots",
    )
    return DaemonSetResult(ready_seconds=ready, update_seconds=time.monotonic() - began)


def delete_daemonsets(api: k8s.ApiClient, namespace: str, timeout: float) -> None:
    """Deletes every DaemonSet of the namespace and waits until their pods are gone."""
    apps, core = k8s.AppsV1Api(api), k8s.CoreV1Api(api)
    apps.delete_collection_namespaced_daemon_set(namespace, propagation_policy="Background")
    wait_for(
        lambda: not core.list_namespaced_pod(namespace, limit=1).items,
        timeout=timeout,
        interval=2.0,
        message="the DaemonSets' pods to be deleted",
    )
