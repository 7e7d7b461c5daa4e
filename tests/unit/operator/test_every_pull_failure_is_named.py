"""A failed pull of any container of a component's pod reaches the CoralInstance as `ImagePullFailed`
with the kubelet's message: the init step that owns the plugin folder, a sidecar, a main container.

Issue 50: on a robot whose registry was down, the pods said `ImagePullBackOff` for the init step
that runs the operator's helper image, while the instance said only `HealthTimeout`.
"""

from __future__ import annotations

from typing import Any

import pytest
from coral_core import names
from coral_operator.kube import observing
from coral_operator.planning import pods
from coral_operator.status import instance_status
from operator_specs import BASE_SPEC, NOW, instance_view, robot
from test_pod_layouts import _instance_spec

# A folder of the namespace's own data subtree: the init step hands it to the components' user.
DATA = {"hostPath": "/var/lib/coral/data/ns/maps", "mountPath": "/maps"}
SPEC = {**BASE_SPEC, "drivers": [{"name": "lidar", "image": "example/lidar:1", "hostPaths": [DATA]}]}
PULL_MESSAGE = (
    'failed to pull and unpack image "127.0.0.1:5999/helper:1": dial tcp 127.0.0.1:5999: connect: '
    "connection refused"
)


def _container_statuses(containers: list[dict[str, Any]], failing: str) -> list[dict[str, Any]]:
    """As the kubelet reports a pod whose `failing` container cannot be pulled: the ones before it
    run, the ones after it wait their turn."""
    statuses, reached = [], False
    for container in containers:
        if container["name"] == failing:
            reached = True
            state = {"waiting": {"reason": "ErrImagePull", "message": PULL_MESSAGE}}
        elif reached:
            state = {"waiting": {"reason": "PodInitializing"}}
        else:
            state = {"running": {"startedAt": "2026-01-01T11:59:50Z"}}
        statuses.append({"name": container["name"], "ready": not reached, "restartCount": 0, "state": state})
    return statuses


def _body(manifest: dict[str, Any], failing: str) -> dict[str, Any]:
    spec = manifest["spec"]
    inits = spec.get("initContainers", [])
    every = _container_statuses([*inits, *spec["containers"]], failing)
    return {
        "metadata": {**manifest["metadata"], "creationTimestamp": "2026-01-01T11:59:40Z"},
        "spec": spec,
        "status": {
            "phase": "Pending",
            "conditions": [{"type": "Ready", "status": "False"}],
            "initContainerStatuses": every[: len(inits)],
            "containerStatuses": every[len(inits) :],
        },
    }


CASES = {
    "the plugin folder's init step, one pod per component": ("PodPerComponent", "lidar", pods.FOLDERS_OWNER),
    "a skillset's own container, one pod per component": ("PodPerComponent", "slam", "slam"),
    "the plugin folder's init step, one pod per robot": ("PodPerRobot", None, pods.FOLDERS_OWNER),
    "a sidecar, one pod per robot": ("PodPerRobot", None, "slam"),
    "the executor, one pod per robot": ("PodPerRobot", None, "executor"),
}


@pytest.mark.parametrize(("layout", "pod_of", "failing"), CASES.values(), ids=CASES.keys())
def test_a_failed_pull_is_named_with_the_kubelets_message(
    layout: str, pod_of: str | None, failing: str
) -> None:
    parsed = _instance_spec({**SPEC, "layout": layout})
    desired = pods.build_pods(spec=parsed, instance="sys-r1", namespace="ns", instance_uid="u")
    bodies = []
    for manifest in desired:
        component = manifest["metadata"]["labels"].get(names.LABEL_COMPONENT)
        if pod_of is None or component == pod_of:
            bodies.append(_body(manifest, failing))
        elif component == "lidar":
            bodies.append(_body(manifest, failing="none"))  # the driver before it runs
    observed = [record for body in bodies for record in observing.observed_pods(body)]
    view = instance_view(parsed, desired, observed, startup=parsed.startup, node=robot("r1"))
    status = instance_status.build_instance_status(view, old_conditions=[], generation=1, now=NOW)
    conditions = {c["type"]: c for c in status["conditions"]}
    components = conditions["ComponentsReady"]
    assert (components["status"], components["reason"]) == ("False", "ImagePullFailed"), components
    assert f"ErrImagePull: {PULL_MESSAGE}" in components["message"], components
    assert conditions["Ready"]["reason"] == "ImagePullFailed"
    if failing == pods.FOLDERS_OWNER:
        assert f"container {pods.FOLDERS_OWNER}: ErrImagePull" in components["message"], components
    # The kubelet keeps trying: a registry that comes back heals the robot, so it is not Stalled.
    assert conditions["Stalled"]["status"] == "False", conditions["Stalled"]
