"""The admission policy behind the executors' shared accounts: a system's account reaches only the
instance of the Node its token is bound to, and never another system's instance on that Node."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest
from coral_api import GROUP, VERSION, Coral, client_as, executor_client, fleet_mission, is_current_and_true
from coral_operator.planning import naming
from kubernetes import client as k8s
from kubernetes.client.exceptions import ApiException

pytestmark = [pytest.mark.cluster, pytest.mark.slow]
MERGE = "application/merge-patch+json"


def _patch_tree(api: k8s.ApiClient, namespace: str, instance: str) -> int:
    """HTTP status of an executor's status patch (200 when admitted)."""
    try:
        k8s.CustomObjectsApi(api).patch_namespaced_custom_object_status(
            GROUP, VERSION, namespace, "coralinstances", instance,
            {"status": {"tree": {"rootStatus": "RUNNING"}}}, _content_type=MERGE,
        )  # fmt: skip
    except ApiException as error:
        return int(error.status)
    return 200


def test_an_executor_reaches_neither_another_system_on_its_robot_nor_anything_unbound(
    cluster: Any,
    namespace: str,
    coral_operator: Any,
    robots: Callable[..., list[str]],
    fleet_label: str,
    wait: Any,
) -> None:
    (robot,) = robots(1, {"fleet": fleet_label})
    coral = Coral(cluster.api_client, namespace)
    for name in ("alpha", "beta"):
        coral.create_system(fleet_mission(name, fleet_label))
    for name in ("alpha", "beta"):
        wait(lambda name=name: is_current_and_true(coral.system(name), "Ready"), f"system {name} to be Ready")
    alpha = executor_client(cluster, namespace, f"alpha-{robot}")

    assert _patch_tree(alpha, namespace, f"alpha-{robot}") == 200
    assert _patch_tree(alpha, namespace, f"beta-{robot}") == 403, (
        "another system's instance on the same robot"
    )
    unbound = client_as(cluster, namespace, naming.executor_account_name("alpha"))
    assert _patch_tree(unbound, namespace, f"alpha-{robot}") == 403, "a token bound to no pod on the robot"
    assert (coral.instances()[f"beta-{robot}"].get("status") or {}).get("tree") is None
