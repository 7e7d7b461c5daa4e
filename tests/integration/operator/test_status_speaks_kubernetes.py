"""Tools read Coral status like built-in kinds: kubectl explain, kubectl wait, Argo CD's health check."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from coral_api import Coral, condition, fleet_mission

lupa = pytest.importorskip("lupa", reason="lupa (test extra) runs the Lua health check")

pytestmark = [pytest.mark.cluster, pytest.mark.slow]
HEALTH = Path(__file__).resolve().parents[3] / "charts" / "coral-operator" / "argocd" / "health.lua"


def argocd_health(obj: dict[str, Any]) -> str:
    runtime = lupa.LuaRuntime()

    def to_lua(value: Any) -> Any:
        if isinstance(value, dict):
            return runtime.table_from({k: to_lua(v) for k, v in value.items()})
        if isinstance(value, list):
            return runtime.table_from([to_lua(v) for v in value])
        return value

    runtime.globals().obj = to_lua(obj)
    return str(runtime.execute(HEALTH.read_text())["status"])


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
    cluster: Any,
    namespace: str,
    coral_operator: Any,
    robots: Callable[..., list[str]],
    fleet_label: str,
    wait: Any,
) -> None:
    robots(2, {"fleet": fleet_label})
    coral = Coral(cluster.api_client, namespace)
    coral.create_system(fleet_mission("fleet", fleet_label))
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
