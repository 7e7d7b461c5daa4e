"""Acceptance 1: a canary that turns unhealthy pauses the rollout (or rolls it back) and no other
robot is touched."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest
from click.testing import CliRunner
from coral_operator.rollout_cli import rollout
from coral_testbed.waiting import holds_for, wait_for
from fleet import Fleet, instance_ready, mission, wait_settled

pytestmark = [pytest.mark.cluster, pytest.mark.slow]


def _start(cluster: Any, namespace: str, robots: Callable[..., list[str]], fleet_label: str, on_failure: str):
    names = robots(3, {"fleet": fleet_label})
    canary = robots(1, {"fleet": fleet_label, "canary": "yes"}, start=9)[0]
    fleet = Fleet(cluster.api_client, namespace, "patrol")
    policy = {
        "maxUnavailable": 2,
        "canary": {"robots": {"matchLabels": {"canary": "yes"}}, "holdSeconds": 600},
        "onFailure": on_failure,
    }
    fleet.create(mission("patrol", fleet_label, policy))
    wait_settled(fleet, 4)
    first = fleet.revisions()[canary]
    pods = {robot: fleet.pod_uids(robot) for robot in names}
    fleet.change("2")
    # The canary moves alone; the rest waits for the hold time.
    wait_for(
        lambda: fleet.revisions()[canary] != first and instance_ready(fleet.instances()[canary]),
        timeout=120,
        message="the canary to run the new revision and be Ready",
    )
    second = fleet.revisions()[canary]
    wait_for(
        lambda: (fleet.rollout().get("canary") or {}).get("healthySince"),
        timeout=60,
        message="the canary hold to start",
    )
    return fleet, names, canary, first, second, pods


def _others_untouched(fleet: Fleet, names: list[str], first: str, pods: dict[str, dict[str, str]]) -> bool:
    revisions = fleet.revisions()
    return all(revisions[r] == first for r in names) and all(fleet.pod_uids(r) == pods[r] for r in names)


def test_an_unhealthy_canary_pauses_the_rollout_and_no_other_robot_is_touched(
    cluster: Any, namespace: str, operator: Any, robots: Callable[..., list[str]], fleet_label: str
) -> None:
    fleet, names, canary, first, second, pods = _start(cluster, namespace, robots, fleet_label, "Pause")
    fleet.set_tree(canary, "FAILURE")
    failure = wait_for(
        lambda: fleet.rollout().get("failure"), timeout=60, message="the rollout to record the failure"
    )
    assert failure["revision"] == second and failure["robots"] == [canary]
    state = fleet.rollout()
    assert state["paused"] and not state["complete"]
    conditions = {c["type"]: c for c in fleet.system()["status"]["conditions"]}
    assert conditions["RolloutComplete"]["reason"] == "HealthGateFailed"
    assert conditions["Stalled"]["status"] == "True"
    assert wait_for(lambda: fleet.events("RolloutFailed"), timeout=30, message="a RolloutFailed Event")
    holds_for(lambda: _others_untouched(fleet, names, first, pods), 8, message="the other robots untouched")
    assert fleet.revisions()[canary] == second

    # The canary recovers; a human sees it healthy on the rollout and resumes: the failure is cleared
    # and the canary hold starts again. (Resumed before the operator saw the recovery, the gate
    # judges the failure it still sees and pauses again, as it should.)
    fleet.set_tree(canary, "SUCCESS")
    wait_for(
        lambda: fleet.rollout().get("canary", {}).get("healthy") == 1,
        timeout=60,
        message=lambda: f"the rollout to count the canary healthy: {fleet.rollout()}",
    )
    runner = CliRunner(env={"KUBECONFIG": str(cluster.kubeconfig)})
    result = runner.invoke(rollout, ["resume", "patrol", "-n", namespace])
    assert result.exit_code == 0, result.output
    wait_for(
        lambda: "failure" not in fleet.rollout() and not fleet.rollout()["paused"],
        timeout=60,
        message=lambda: f"the failure to be cleared: {fleet.rollout()}",
    )
    assert fleet.rollout()["canary"]["healthySince"]
    assert "Traceback" not in operator.logs()


def test_an_unhealthy_canary_rolls_back_when_the_policy_says_so(
    cluster: Any, namespace: str, operator: Any, robots: Callable[..., list[str]], fleet_label: str
) -> None:
    fleet, names, canary, first, second, pods = _start(cluster, namespace, robots, fleet_label, "Rollback")
    fleet.set_tree(canary, "FAILURE")
    wait_for(
        lambda: (
            fleet.revisions()[canary] == first
            and fleet.instances()[canary]["status"].get("revision") == first
        ),
        timeout=120,
        message="the canary to return to the first revision",
    )
    # Its tree reported FAILURE, so it is not Ready until the executor reports a new run.
    fleet.set_tree(canary, "RUNNING")
    wait_for(
        lambda: instance_ready(fleet.instances()[canary]),
        timeout=60,
        message="the canary Ready once its executor reports a running tree",
    )
    rolled = fleet.rollout()["rolledBack"]
    assert rolled == {"fromRevision": second, "toRevision": first, "reason": "HealthGateFailed"}
    assert _others_untouched(fleet, names, first, pods)
    assert wait_for(
        lambda: fleet.events("RolloutRolledBack"), timeout=30, message="a RolloutRolledBack Event"
    )
    assert "Traceback" not in operator.logs()
