"""Pod manifests and status helpers shared by the robot-runner tests."""

from __future__ import annotations

from typing import Any

from coral_testbed.waiting import wait_for
from kubernetes import client as k8s
from kubernetes.client.exceptions import ApiException


def python_pod(
    name: str,
    robot: str,
    code: str,
    *,
    restart: str = "Never",
    env: list[dict[str, Any]] | None = None,
    extra: dict[str, Any] | None = None,
    host_path: str = "/srv/data",
) -> dict[str, Any]:
    """A pod pinned to `robot` running `python -c code` with a hostPath mounted at /data."""
    container: dict[str, Any] = {
        "name": "main",
        "image": "example.org/coral/test:1.0",
        "command": ["python", "-c", code],
        "env": env or [],
        "volumeMounts": [{"name": "data", "mountPath": "/data"}],
        **(extra or {}),
    }
    return {
        "apiVersion": "v1",
        "kind": "Pod",
        "metadata": {"name": name},
        "spec": {
            "nodeName": robot,
            "restartPolicy": restart,
            "terminationGracePeriodSeconds": 5,
            "containers": [container],
            "volumes": [{"name": "data", "hostPath": {"path": host_path, "type": "DirectoryOrCreate"}}],
        },
    }


def read_pod(core: k8s.CoreV1Api, name: str, namespace: str) -> k8s.V1Pod | None:
    try:
        return core.read_namespaced_pod(name, namespace)
    except ApiException as error:
        if error.status == 404:
            return None
        raise


def wait_phase(core: k8s.CoreV1Api, name: str, namespace: str, phases: tuple[str, ...], timeout: float = 60):
    """Waits until the pod's phase is one of `phases`; returns the pod."""
    seen: list[Any] = [None]

    def reached() -> k8s.V1Pod | None:
        pod = read_pod(core, name, namespace)
        seen[0] = pod.status.phase if pod and pod.status else None
        return pod if seen[0] in phases else None

    return wait_for(reached, timeout=timeout, message=lambda: f"pod {name} in {phases} (phase {seen[0]})")


def is_ready(pod: k8s.V1Pod) -> bool:
    return any(c.type == "Ready" and c.status == "True" for c in pod.status.conditions or [])
