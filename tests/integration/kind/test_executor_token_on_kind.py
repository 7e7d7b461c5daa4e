"""The token a kind robot's kubelet projects into a real executor container may patch its own
CoralInstance's status and nothing else: no other instance, no pods, no secrets, no CoralSystems."""

from __future__ import annotations

import base64
import json
from typing import Any

import pytest
from coral_core.names import GROUP, VERSION
from coral_operator.planning.pods import SERVICE_ACCOUNT_DIR
from coral_testbed.kind.missions import KindMissionStack
from coral_testbed.waiting import wait_for
from fixtures.apiclients import client_with_token, denied
from kubernetes import client as k8s
from missions import realsystems as rs

from .fleet import ROBOTS

pytestmark = [pytest.mark.slow, pytest.mark.timeout(1800)]

MERGE = "application/merge-patch+json"
# An executor with nothing to wait for: its tree sleeps while the test borrows its token.
GUARD_TREE = """<root BTCPP_format="4" main_tree_to_execute="Main">
  <BehaviorTree ID="Main"><Sleep msec="600000"/></BehaviorTree>
</root>
"""


def _guard_system() -> dict[str, Any]:
    """An executor on every kind robot: one CoralInstance each."""
    return {
        "apiVersion": f"{GROUP}/{VERSION}",
        "kind": "CoralSystem",
        "metadata": {"name": "guard"},
        "spec": {
            "robots": {"matchLabels": {"coral.dev/model": "kind"}},
            "parameters": {"inline": "executor:\n  ros__parameters: {}\n"},
            "tree": {"inline": GUARD_TREE, "tickRateHz": 5.0},
            "executors": [{"name": "executor", "image": "coral/executor:0.1.0"}],
        },
    }


def _claims(token: str) -> dict[str, Any]:
    payload = token.split(".")[1]
    return json.loads(base64.urlsafe_b64decode(payload + "=" * (-len(payload) % 4)))


def test_the_executors_projected_token_patches_its_own_status_and_nothing_else(
    kind_operator: KindMissionStack,
) -> None:
    robot, other_robot = sorted(ROBOTS)[:2]
    namespace, cluster = kind_operator.namespace, kind_operator.cluster
    core, custom_admin = kind_operator.core, kind_operator.custom
    rs.create(custom_admin, namespace, _guard_system())

    def running_executor() -> k8s.V1Pod | None:
        pods = core.list_namespaced_pod(
            namespace,
            label_selector=f"coral.dev/system=guard,coral.dev/role=executor,coral.dev/robot={robot}",
        ).items
        return next((p for p in pods if p.status.phase == "Running"), None)

    pod = wait_for(running_executor, timeout=180, message="the guard's executor container to run")

    def root_status(robot: str) -> str | None:
        return rs.tree(kind_operator.instance_of(robot) or {}).get("rootStatus")

    wait_for(
        lambda: root_status(robot) == "RUNNING" and root_status(other_robot) == "RUNNING",
        timeout=120,
        message=lambda: f"the executors' own tree status on their instances: {kind_operator.instances()}",
    )
    mine = kind_operator.instance_of(robot)["metadata"]["name"]
    other = kind_operator.instance_of(other_robot)["metadata"]["name"]
    token = cluster.kubectl(
        "exec", "-n", namespace, pod.metadata.name, "-c", "executor", "--",
        "cat", f"{SERVICE_ACCOUNT_DIR}/token",
    ).stdout.strip()  # fmt: skip
    # The kubelet's bound token: it names the pod it was projected into.
    identity = _claims(token)["kubernetes.io"]
    assert identity["pod"]["name"] == pod.metadata.name
    assert identity["serviceaccount"]["name"] == pod.spec.service_account_name

    as_executor = client_with_token(cluster, token)
    custom = k8s.CustomObjectsApi(as_executor)
    as_core = k8s.CoreV1Api(as_executor)

    custom.patch_namespaced_custom_object_status(
        GROUP, VERSION, namespace, "coralinstances", mine,
        {"status": {"tree": {"rootStatus": "RUNNING"}}}, _content_type=MERGE,
    )  # fmt: skip
    refused = {
        "another instance's status": lambda: custom.patch_namespaced_custom_object_status(
            GROUP, VERSION, namespace, "coralinstances", other,
            {"status": {"tree": {"rootStatus": "FAILURE"}}}, _content_type=MERGE,
        ),
        "its own instance's spec": lambda: custom.patch_namespaced_custom_object(
            GROUP, VERSION, namespace, "coralinstances", mine, {"spec": {"robot": "x"}}, _content_type=MERGE
        ),
        "a CoralSystem's status": lambda: custom.patch_namespaced_custom_object_status(
            GROUP, VERSION, namespace, "coralsystems", "guard", {"status": {}}, _content_type=MERGE
        ),
        "listing CoralSystems": lambda: custom.list_namespaced_custom_object(
            GROUP, VERSION, namespace, "coralsystems"
        ),
        "its own pod": lambda: as_core.patch_namespaced_pod(
            pod.metadata.name, namespace, {"metadata": {"labels": {"x": "y"}}}, _content_type=MERGE
        ),
        "listing pods": lambda: as_core.list_namespaced_pod(namespace),
        "listing secrets": lambda: as_core.list_namespaced_secret(namespace),
    }  # fmt: skip
    allowed = [what for what, call in refused.items() if not denied(call)]
    assert not allowed, f"the executor's token was not refused: {allowed}"
    assert root_status(other_robot) == "RUNNING"
    assert "x" not in core.read_namespaced_pod(pod.metadata.name, namespace).metadata.labels
