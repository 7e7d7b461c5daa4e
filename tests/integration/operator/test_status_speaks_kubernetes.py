"""Tools read Coral status like built-in kinds: kubectl explain, kubectl wait, Argo CD's health check."""

from __future__ import annotations

from typing import Any

import pytest
from coral_api import condition
from fixtures import argocd
from scenarios import Scenario

pytest.importorskip("lupa", reason="lupa (test extra) runs the Lua health check")

pytestmark = [pytest.mark.cluster, pytest.mark.slow]


def argocd_health(obj: dict[str, Any]) -> str:
    return argocd.health(obj)["status"]


def test_kubectl_explain_describes_the_fields(cluster: Any, coral_crds: None, wait: Any) -> None:
    def explain(field: str) -> str:
        # The API server publishes a new CRD's OpenAPI a moment after it is Established.
        return wait(
            lambda: cluster.kubectl("explain", field, check=False).stdout,
            f"kubectl explain {field}",
            timeout=60,
        )

    text = explain("coralsystem.spec.ros.domainId")
    assert "ROS_DOMAIN_ID" in text
    text = explain("coralinstance.status.tree")
    assert "Tree status, written by the executor" in text


def test_kubectl_wait_and_argo_cd_follow_a_system_from_progressing_to_healthy_to_degraded(
    scenario: Scenario,
) -> None:
    cluster, namespace, coral, wait = scenario.cluster, scenario.namespace, scenario.coral, scenario.wait
    scenario.robots(2)
    coral.create_system(scenario.mission())
    assert argocd_health(coral.system("fleet")) == "Progressing"
    cluster.kubectl(
        "wait", "--for=condition=Ready", "coralsystem/fleet", "-n", namespace, "--timeout=120s", timeout=130
    )
    assert argocd_health(coral.system("fleet")) == "Healthy"
    for instance in coral.instances().values():
        assert argocd_health(instance) == "Healthy"

    coral.patch_system("fleet", {"spec": {"parameters": {"inline": "slam:\n  ros__parameters: [\n"}}})
    wait(lambda: argocd_health(coral.system("fleet")) == "Degraded", "Argo CD to see the bad parameters")
    stalled = condition(coral.system("fleet"), "Stalled")
    assert stalled["reason"] == "InvalidParameters"
    assert "coralsystem/fleet spec.parameters.inline:" in stalled["message"]
    result = cluster.kubectl(
        "wait", "--for=condition=Stalled", "coralsystem/fleet", "-n", namespace, "--timeout=30s", timeout=40
    )
    assert "condition met" in result.stdout
