"""Images pulled onto robots before a test or a demo step whose timing must not include a cold pull
(a startup's health timeout, a halt's two seconds): one short pod per image, bound to the robot."""

from __future__ import annotations

from typing import Any

from kubernetes import client as k8s

from coral_testbed.waiting import wait_for

PULL_POD_PREFIX = "pull-"


def pull_images(
    api: k8s.ApiClient, namespace: str, node: str, references: list[str], timeout: float = 300
) -> None:
    """Has the Node `node` pull `references`: one pod per image, bound to it, whose container exits
    at once; the pods are deleted after."""
    core = k8s.CoreV1Api(api)
    names = [f"{PULL_POD_PREFIX}{index}" for index in range(len(references))]
    for name, reference in zip(names, references, strict=True):
        container = {"name": "pull", "image": reference, "command": ["true"]}
        spec = {"nodeName": node, "restartPolicy": "Never", "containers": [container]}
        core.create_namespaced_pod(namespace, {"metadata": {"name": name}, "spec": spec})

    def pulled() -> bool:
        phases = [core.read_namespaced_pod(name, namespace).status.phase for name in names]
        return all(phase == "Succeeded" for phase in phases)

    wait_for(pulled, timeout=timeout, interval=1, message=lambda: f"{node} to pull {references}")
    for name in names:
        core.delete_namespaced_pod(name, namespace, grace_period_seconds=0)


def system_images(system: dict[str, Any]) -> set[str]:
    """Every image a CoralSystem's components run."""
    spec = system["spec"]
    return {c["image"] for kind in ("drivers", "skillsets", "executors") for c in spec.get(kind, [])}


def pull_system_images(
    api: k8s.ApiClient, namespace: str, nodes: list[str], system: dict[str, Any], helper_image: str
) -> None:
    """Has every Node of `nodes` pull the images of `system` and the operator's helper, one after
    the other (the pull pods of each take the same names)."""
    core = k8s.CoreV1Api(api)
    for node in nodes:
        pull_images(api, namespace, node, sorted(system_images(system) | {helper_image}))
        wait_for(
            lambda: (
                not [
                    p
                    for p in core.list_namespaced_pod(namespace).items
                    if p.metadata.name.startswith(PULL_POD_PREFIX)
                ]
            ),
            timeout=60,
            message="the pull pods gone",
        )
