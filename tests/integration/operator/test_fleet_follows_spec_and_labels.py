"""A spec change updates what changed; robots leaving the selector lose their instance; deletion cleans up."""

from __future__ import annotations

from typing import Any

import pytest
from coral_api import Coral, is_current_and_true
from scenarios import Scenario

pytestmark = [pytest.mark.cluster, pytest.mark.slow]


def _key(pod: Any) -> tuple[str, str]:
    # A replaced pod gets a new name (it ends in a content digest), so pods are compared by what they run.
    return pod.metadata.labels["coral.dev/robot"], pod.metadata.labels["coral.dev/component"]


def _uids(coral: Coral) -> dict[tuple[str, str], str]:
    return {
        _key(pod): pod.metadata.uid
        for pod in coral.pods().values()
        if pod.metadata.deletion_timestamp is None
    }


def _is_executor(pod: Any) -> bool:
    return pod.metadata.labels["coral.dev/role"] == "executor"


def test_spec_changes_labels_and_deletion(scenario: Scenario) -> None:
    cluster, namespace, coral, wait = scenario.cluster, scenario.namespace, scenario.coral, scenario.wait
    first, second = scenario.robots(2)
    scenario.deploy()
    before = _uids(coral)
    assert len(before) == 6

    # A new executor image replaces the executor pods only.
    coral.patch_system(
        "fleet",
        [{"op": "replace", "path": "/spec/executors/0/image", "value": "coral-on-kubernetes/executor:0.2.0"}],
        content_type="application/json-patch+json",
    )

    def updated() -> bool:
        system = coral.system("fleet")
        pods = coral.pods()
        images = {p.spec.containers[0].image for p in pods.values() if _is_executor(p)}
        return is_current_and_true(system, "Ready") and images == {"coral-on-kubernetes/executor:0.2.0"}

    wait(updated, "the executors to run the new image and the system to be Ready again")
    after = _uids(coral)
    for key, uid in before.items():
        if key[1] == "executor":
            assert after[key] != uid, f"{key} was not replaced"
        else:
            assert after[key] == uid, f"{key} was restarted although its component did not change"
    revision = coral.system("fleet")["status"]["revision"]
    assert {i["spec"]["revision"] for i in coral.instances().values()} == {revision}
    assert {p.metadata.labels["coral.dev/revision"] for p in coral.pods().values()} == {revision}

    # The second robot loses the label: its instance and pods go, the first robot keeps its own.
    cluster.kubectl("label", "node", second, "fleet-")
    wait(
        lambda: (
            set(coral.instances()) == {f"fleet-{first}"}
            and all(p.metadata.labels["coral.dev/robot"] == first for p in coral.pods().values())
        ),
        "the unlabelled robot's instance and pods to be gone",
    )
    assert all(after[_key(p)] == p.metadata.uid for p in coral.pods().values())
    wait(lambda: (coral.system("fleet")["status"]["robots"]["matched"]) == 1, "the system to count one robot")

    # Deleting the system removes everything through owner references (no finalizers).
    coral.delete_system("fleet")
    # The executors' ServiceAccounts hang off the instances, so they go one collection later.
    wait(
        lambda: (
            not coral.instances()
            and not coral.pods()
            and not coral.config_maps()
            and [a.metadata.name for a in coral.core.list_namespaced_service_account(namespace).items]
            == ["default"]
        ),
        "instances, pods, ConfigMaps and the executors' ServiceAccounts to be garbage collected",
    )
