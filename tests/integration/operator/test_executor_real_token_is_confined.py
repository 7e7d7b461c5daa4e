"""The token the kubelet projects into a real executor container may patch its own CoralInstance's
status and nothing else: no other instance, no pods, no secrets, no CoralSystems."""

from __future__ import annotations

import base64
import json
from collections.abc import Callable
from typing import Any

import pytest
from coral_api import GROUP, VERSION, Coral, fleet_mission, is_current_and_true
from coral_operator.planning.pods import SERVICE_ACCOUNT_DIR
from coral_testbed.cluster import realrobots
from fixtures.operator import HelmOperator
from fixtures.robots import REAL_ROBOTS
from kubernetes import client as k8s
from kubernetes.client.exceptions import ApiException

pytestmark = [pytest.mark.cluster, pytest.mark.real_robots, pytest.mark.slow]

MERGE = "application/merge-patch+json"
# An executor with nothing to wait for: its tree sleeps while the test borrows its token.
GUARD_TREE = """<root BTCPP_format="4" main_tree_to_execute="Main">
  <BehaviorTree ID="Main"><Sleep msec="600000"/></BehaviorTree>
</root>
"""


def _guard_system(robot: str) -> dict[str, Any]:
    return {
        "apiVersion": f"{GROUP}/{VERSION}",
        "kind": "CoralSystem",
        "metadata": {"name": "guard"},
        "spec": {
            "robots": {"matchLabels": {"coral.dev/robot": robot}},
            "parameters": {"inline": "executor:\n  ros__parameters: {}\n"},
            "tree": {"inline": GUARD_TREE, "tickRateHz": 5.0},
            "executors": [{"name": "executor", "image": "coral/executor:0.1.0"}],
        },
    }


def _denied(call: Callable[[], Any]) -> bool:
    try:
        call()
    except ApiException as error:
        return error.status == 403
    return False


def _claims(token: str) -> dict[str, Any]:
    payload = token.split(".")[1]
    return json.loads(base64.urlsafe_b64decode(payload + "=" * (-len(payload) % 4)))


def test_the_executors_projected_token_patches_its_own_status_and_nothing_else(
    cluster: Any,
    namespace: str,
    helm_operator: HelmOperator,
    real_robots: realrobots.RealRobots,
    robots: Callable[..., list[str]],
    fleet_label: str,
    wait: Any,
) -> None:
    robot = REAL_ROBOTS[0]
    coral = Coral(cluster.api_client, namespace)
    core = k8s.CoreV1Api(cluster.api_client)
    robots(1, {"fleet": fleet_label})
    coral.create_system(fleet_mission("fleet", fleet_label))
    coral.create_system(_guard_system(robot))
    wait(lambda: is_current_and_true(coral.system("fleet"), "Ready"), "the kwok system to become Ready")

    def running_executor() -> k8s.V1Pod | None:
        pods = core.list_namespaced_pod(
            namespace, label_selector="coral.dev/system=guard,coral.dev/role=executor"
        ).items
        return next((p for p in pods if p.status.phase == "Running"), None)

    pod = wait(running_executor, "the guard's executor container to run", timeout=180)
    mine = f"guard-{robot}"
    wait(
        lambda: (
            ((coral.instances().get(mine) or {}).get("status") or {}).get("tree", {}).get("rootStatus")
            == "RUNNING"
        ),
        "the executor's own tree status on its instance",
        timeout=120,
    )
    token = cluster.kubectl(
        "exec", "-n", namespace, pod.metadata.name, "-c", "executor", "--",
        "cat", f"{SERVICE_ACCOUNT_DIR}/token",
    ).stdout.strip()  # fmt: skip
    # The kubelet's bound token: it names the pod it was projected into.
    identity = _claims(token)["kubernetes.io"]
    assert identity["pod"]["name"] == pod.metadata.name
    assert identity["serviceaccount"]["name"] == pod.spec.service_account_name

    base = cluster.api_client.configuration
    configuration = k8s.Configuration()
    configuration.host = base.host
    configuration.ssl_ca_cert = base.ssl_ca_cert
    configuration.verify_ssl = base.verify_ssl
    configuration.api_key = {"authorization": f"Bearer {token}"}
    as_executor = k8s.ApiClient(configuration)
    custom = k8s.CustomObjectsApi(as_executor)
    as_core = k8s.CoreV1Api(as_executor)

    custom.patch_namespaced_custom_object_status(
        GROUP, VERSION, namespace, "coralinstances", mine,
        {"status": {"tree": {"rootStatus": "RUNNING"}}}, _content_type=MERGE,
    )  # fmt: skip
    other = next(name for name in coral.instances() if name != mine)
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
    allowed = [what for what, call in refused.items() if not _denied(call)]
    assert not allowed, f"the executor's token was not refused: {allowed}"
    assert (coral.instances()[other].get("status") or {}).get("tree") is None
    assert "x" not in core.read_namespaced_pod(pod.metadata.name, namespace).metadata.labels
