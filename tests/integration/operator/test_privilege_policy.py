"""The operator refuses a CoralSystem asking for more privilege than its policy allows, deploying nothing."""

from __future__ import annotations

import pytest
from coral_api import condition
from coral_testbed.waiting import holds_for
from scenarios import Scenario

pytestmark = [pytest.mark.cluster, pytest.mark.slow]


@pytest.fixture
def operator_env() -> dict[str, str]:
    return {
        "CORAL_POLICY_PRIVILEGED_NAMESPACES": "robots-hardware",
        "CORAL_POLICY_HOST_PATHS": "*=/dev,*=/var/lib/coral/bags",
    }


def test_a_privileged_driver_outside_the_allowed_namespaces_is_refused(scenario: Scenario) -> None:
    coral, wait, namespace = scenario.coral, scenario.wait, scenario.namespace
    scenario.robots(1)
    mission = scenario.mission()
    mission["spec"]["drivers"][0] |= {
        "privileged": True,
        "hostPaths": [{"hostPath": "/etc/ssh", "mountPath": "/etc/ssh"}],
    }
    coral.create_system(mission)
    stalled = wait(
        lambda: condition(coral.system("fleet"), "Stalled").get("status") == "True" and coral.system("fleet"),
        "the system to be refused",
    )
    message = condition(stalled, "Stalled")["message"]
    assert condition(stalled, "Stalled")["reason"] == "PolicyDenied"
    assert f"spec.drivers[0] (lidar-driver): privileged is not allowed in namespace {namespace}" in message
    assert f"host path /etc/ssh is outside the folders namespace {namespace} may mount" in message
    holds_for(lambda: not coral.instances() and not coral.pods(), duration=3, message="nothing deployed")
