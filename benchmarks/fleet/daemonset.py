"""The baselines: DaemonSets running the very pods Coral plans for the benchmark's mission.

Each DaemonSet's pod template is the pod the operator would create for one robot of the same
CoralSystem (`fleet.coral.build_system`), from the operator's own planner: the same containers
with their images, environment, probes, mounts and security context, the same volumes, host
network and IPC, tolerations and executor ServiceAccount. So the runs compare controllers, not pod
sizes: the API server's and kwok's work per pod grows with the pod. What a DaemonSet cannot carry
is changed: no `nodeName` (the DaemonSet places its pods) and `restartPolicy: Always` (the only
one it accepts). Two shapes, as Kubernetes would run the mission without Coral:

- the floor, one DaemonSet with the `PodPerRobot` pod (one pod per robot);
- the same shape as Coral's default layout, one DaemonSet per `PodPerComponent` pod (three pods
  per robot).

`run_daemonsets` measures the time until every pod of the given DaemonSets is Ready and the time
of a rolling update at the same `maxUnavailable` after the same environment variable changes as
in the Coral runs.
"""

from __future__ import annotations

import copy
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from coral_operator import config
from coral_operator.api.instance import CoralInstanceSpec
from coral_operator.api.system import CoralSystemSpec
from coral_operator.planning import instances, naming, pods
from coral_operator.planning.observed import RobotNode
from coral_testbed.waiting import wait_for
from kubernetes import client as k8s
from kubernetes.client.exceptions import ApiException

from fleet import coral
from fleet.robots import FLEET_LABEL

NAME = coral.NAME


def coral_pods(namespace: str, revision: str, layout: str) -> list[dict[str, Any]]:
    """The pods the operator plans for one robot of the benchmark's system at `revision`."""
    spec = CoralSystemSpec.model_validate(coral.build_system(namespace, revision, "10%", layout)["spec"])
    robot = RobotNode(node_name="robot-0000", robot="robot-0000", labels={FLEET_LABEL: "bench"}, ready=True)
    template = instances.build_template(spec, f"{NAME}-tree", f"{NAME}-parameters")
    instance = CoralInstanceSpec.model_validate(instances.build_instance_spec(NAME, robot, template))
    # The same policy as the operator's in the Coral runs, so the host folders mount alike.
    settings = pods.PodSettings(policy=config.from_environment(coral.policy_environment(namespace)).policy)
    return pods.build_pods(
        spec=instance, instance=f"{NAME}-robot-0000", namespace=namespace, instance_uid="", settings=settings
    )


def build_daemonset(namespace: str, name: str, pod: dict[str, Any], max_unavailable: str) -> dict[str, Any]:
    """A DaemonSet whose template is `pod` (as Coral plans it) on every benchmark robot."""
    labels = {"app": name}
    template = copy.deepcopy(pod["spec"])
    template.pop("nodeName", None)
    template["restartPolicy"] = "Always"
    template["nodeSelector"] = {FLEET_LABEL: "bench"}
    return {
        "apiVersion": "apps/v1",
        "kind": "DaemonSet",
        "metadata": {"name": name, "namespace": namespace},
        "spec": {
            "selector": {"matchLabels": labels},
            "updateStrategy": {"type": "RollingUpdate", "rollingUpdate": {"maxUnavailable": max_unavailable}},
            "template": {"metadata": {"labels": labels}, "spec": template},
        },
    }


def single(namespace: str, revision: str, max_unavailable: str) -> list[dict[str, Any]]:
    """The floor: one DaemonSet, the `PodPerRobot` pod on every robot."""
    (pod,) = coral_pods(namespace, revision, "PodPerRobot")
    return [build_daemonset(namespace, NAME, pod, max_unavailable)]


def per_component(namespace: str, revision: str, max_unavailable: str) -> list[dict[str, Any]]:
    """Coral's shape: one DaemonSet per `PodPerComponent` pod, three pods per robot."""
    return [
        build_daemonset(namespace, pod["spec"]["containers"][0]["name"], pod, max_unavailable)
        for pod in coral_pods(namespace, revision, "PodPerComponent")
    ]


def create_executor_account(api: k8s.ApiClient, namespace: str) -> None:
    """The ServiceAccount the executor's pods name (the operator makes it for the Coral runs)."""
    account = {"metadata": {"name": naming.executor_account_name(NAME), "namespace": namespace}}
    try:
        k8s.CoreV1Api(api).create_namespaced_service_account(namespace, account)
    except ApiException as error:
        if error.status != 409:
            raise


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
