"""Acceptance 2: a robot reporting a RUNNING tree is not restarted while the update lock holds; it
updates when the tree finishes."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest
from coral_testbed.waiting import holds_for, wait_for
from fleet import Fleet, mission, wait_settled

pytestmark = [pytest.mark.cluster, pytest.mark.slow]


def test_a_robot_in_mission_keeps_its_pods_until_its_tree_finishes(
    cluster: Any, namespace: str, operator: Any, robots: Callable[..., list[str]], fleet_label: str
) -> None:
    busy, *idle = robots(3, {"fleet": fleet_label})
    fleet = Fleet(cluster.api_client, namespace, "patrol")
    fleet.create(mission("patrol", fleet_label, {"maxUnavailable": "100%"}))
    wait_settled(fleet, 3)
    first = fleet.revisions()[busy]
    fleet.set_tree(busy, "RUNNING")
    wait_for(lambda: fleet.system()["status"]["trees"]["running"] == 1, timeout=60, message="RUNNING counted")
    pods = fleet.pod_uids(busy)

    fleet.change("2")
    wait_for(
        lambda: all(fleet.revisions()[r] != first for r in idle),
        timeout=90,
        message="the idle robots to move to the new revision",
    )
    wait_for(lambda: fleet.rollout().get("waitingFor") == [busy], timeout=60, message="the lock reported")
    holds_for(
        lambda: fleet.revisions()[busy] == first and fleet.pod_uids(busy) == pods,
        6,
        message="the robot in mission untouched",
    )
    conditions = {c["type"]: c for c in fleet.system()["status"]["conditions"]}
    assert conditions["RolloutComplete"]["reason"] == "WaitingForRunningTrees"
    assert fleet.events("WaitingForRunningTrees")

    fleet.set_tree(busy, "SUCCESS")
    wait_settled(fleet, 3)
    assert fleet.revisions()[busy] != first
    # The change touched the skillset only: its pod was replaced, the others were relabelled.
    after = fleet.pod_uids(busy)
    assert [component for component, uid in after.items() if pods.get(component) != uid] == ["slam"]


def test_interrupting_running_trees_when_the_rollout_says_so(
    cluster: Any, namespace: str, operator: Any, robots: Callable[..., list[str]], fleet_label: str
) -> None:
    busy, _ = robots(2, {"fleet": fleet_label})
    fleet = Fleet(cluster.api_client, namespace, "patrol")
    fleet.create(mission("patrol", fleet_label, {"maxUnavailable": 1, "interruptRunningTrees": True}))
    wait_settled(fleet, 2)
    first = fleet.revisions()[busy]
    fleet.set_tree(busy, "RUNNING")
    wait_for(lambda: fleet.system()["status"]["trees"]["running"] == 1, timeout=60, message="RUNNING counted")
    fleet.change("2")
    wait_for(
        lambda: fleet.revisions()[busy] != first, timeout=90, message="the busy robot to be moved anyway"
    )
