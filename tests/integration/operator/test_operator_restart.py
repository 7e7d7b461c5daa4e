"""Restarting the operator creates no duplicate pods and loses no status."""

from __future__ import annotations

import pytest
from coral_api import condition, is_current_and_true
from scenarios import Scenario

pytestmark = [pytest.mark.cluster, pytest.mark.slow]


def test_a_restarted_operator_picks_up_where_it_stopped(scenario: Scenario) -> None:
    coral, wait, coral_operator = scenario.coral, scenario.wait, scenario.operator
    scenario.robots(2)
    scenario.deploy()
    pods = {n: p.metadata.uid for n, p in coral.pods().items()}
    ready_since = condition(coral.system("fleet"), "Ready")["lastTransitionTime"]
    instance_ready = {n: condition(i, "Ready")["lastTransitionTime"] for n, i in coral.instances().items()}

    coral_operator.stop()
    coral_operator.start()
    # A robot joining proves the new process is reconciling before anything is compared.
    scenario.robots(1, start=3)
    wait(
        lambda: (
            coral.system("fleet")["status"]["robots"]["ready"] == 3
            and is_current_and_true(coral.system("fleet"), "Ready")
        ),
        lambda: (
            f"the new operator to bring the third robot up: {coral.system('fleet').get('status')}\n"
            f"the operator's last words:\n{coral_operator.logs()[-4000:]}"
        ),
    )

    after = coral.pods()
    assert len(after) == 9
    for name, uid in pods.items():
        assert after[name].metadata.uid == uid, f"{name} was recreated"
    instances = coral.instances()
    for name, since in instance_ready.items():
        assert condition(instances[name], "Ready")["lastTransitionTime"] == since, name
    # The system went Updating and back to Ready for the new robot; conditions that did not flip keep
    # the times the first operator wrote.
    assert condition(coral.system("fleet"), "Stalled")["lastTransitionTime"] <= ready_since
    assert "Traceback" not in coral_operator.logs()
