"""Restarting the operator creates no duplicate pods and loses no status."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest
from coral_api import Coral, condition, fleet_mission, is_current_and_true

pytestmark = [pytest.mark.cluster, pytest.mark.slow]


def test_a_restarted_operator_picks_up_where_it_stopped(
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
    wait(lambda: is_current_and_true(coral.system("fleet"), "Ready"), "the system to become Ready")
    pods = {n: p.metadata.uid for n, p in coral.pods().items()}
    ready_since = condition(coral.system("fleet"), "Ready")["lastTransitionTime"]
    instance_ready = {n: condition(i, "Ready")["lastTransitionTime"] for n, i in coral.instances().items()}

    coral_operator.stop()
    coral_operator.start()
    # A robot joining proves the new process is reconciling before anything is compared.
    robots(1, {"fleet": fleet_label}, start=3)
    wait(
        lambda: (
            coral.system("fleet")["status"]["robots"]["ready"] == 3
            and is_current_and_true(coral.system("fleet"), "Ready")
        ),
        "the new operator to bring the third robot up",
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
