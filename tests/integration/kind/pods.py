"""Plain pods on kind robots and their waits, for the tests of the kubelet and containerd a robot runs.

`robot_pod` is a pod of the busybox test image (sh, sleep, wget, httpd, ip...: the image
`coral_testbed.cluster.nodeimages` packs, loaded into the nodes by conftest's `robot_test_image`)
pinned to a robot by its label, with the robots' tolerations.
"""

from __future__ import annotations

from typing import Any

import yaml
from coral_testbed.cluster import nodeimages
from coral_testbed.cluster.client import Cluster
from coral_testbed.waiting import wait_for
from kubernetes import client as k8s

ROBOT_TOLERATIONS = [
    {"key": "node.kubernetes.io/unreachable", "operator": "Exists", "effect": "NoExecute"},
    {"key": "node.kubernetes.io/not-ready", "operator": "Exists", "effect": "NoExecute"},
]


def robot_pod(
    name: str,
    robot: str,
    script: str,
    host_network: bool = False,
    readiness: list[str] | None = None,
    host_path: str | None = None,
) -> str:
    """A busybox pod pinned to `robot` that runs `script`, as YAML for `kubectl apply -f -`."""
    container: dict[str, Any] = {
        "name": "main",
        "image": nodeimages.TEST_IMAGE,
        "command": ["sh", "-c", script],
    }
    spec: dict[str, Any] = {
        "nodeSelector": {"coral.dev/robot": robot},
        "tolerations": ROBOT_TOLERATIONS,
        "hostNetwork": host_network,
        "terminationGracePeriodSeconds": 1,
        "containers": [container],
    }
    if readiness:
        container["readinessProbe"] = {
            "exec": {"command": readiness},
            "periodSeconds": 1,
            "failureThreshold": 1,
        }
    if host_path:
        container["volumeMounts"] = [{"name": "shared", "mountPath": "/shared"}]
        spec["volumes"] = [{"name": "shared", "hostPath": {"path": host_path, "type": "DirectoryOrCreate"}}]
    return yaml.safe_dump({"apiVersion": "v1", "kind": "Pod", "metadata": {"name": name}, "spec": spec})


def apply_robot_pod(
    cluster: Cluster, namespace: str, name: str, robot: str, script: str, **options: Any
) -> None:
    """Creates `robot_pod(name, robot, script, **options)` in `namespace`."""
    cluster.kubectl("apply", "-n", namespace, "-f", "-", input=robot_pod(name, robot, script, **options))


def condition(pod: Any, kind: str) -> str | None:
    return next((c.status for c in pod.status.conditions or [] if c.type == kind), None)


def wait_pod(core: k8s.CoreV1Api, namespace: str, name: str, ready: bool = True, timeout: float = 120) -> Any:
    """Waits until the pod runs with Ready=`ready`; returns it."""
    seen: list[Any] = [None]

    def there() -> bool:
        pod = seen[0] = core.read_namespaced_pod(name, namespace)
        return pod.status.phase == "Running" and condition(pod, "Ready") == str(ready)

    wait_for(
        there,
        timeout=timeout,
        interval=0.5,
        message=lambda: (
            f"pod {namespace}/{name} Running with Ready={ready} (last: {seen[0] and seen[0].status})"
        ),
    )
    return seen[0]


def events_for(core: k8s.CoreV1Api, namespace: str, name: str) -> list[Any]:
    selector = f"involvedObject.name={name},involvedObject.kind=Pod"
    return core.list_namespaced_event(namespace, field_selector=selector).items
