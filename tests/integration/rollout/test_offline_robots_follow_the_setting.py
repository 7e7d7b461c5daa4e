"""Acceptance 3: an offline robot is skipped or waited for according to `offlineRobots`."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest
from coral_testbed.waiting import holds_for, wait_for
from fleet import Fleet, mission, rollout_complete, wait_settled

pytestmark = [pytest.mark.cluster, pytest.mark.slow]


def _deploy(cluster: Any, namespace: str, robots: Callable[..., list[str]], fleet_label: str, mode: str):
    names = robots(3, {"fleet": fleet_label})
    fleet = Fleet(cluster.api_client, namespace, "patrol")
    fleet.create(mission("patrol", fleet_label, {"maxUnavailable": 1, "offlineRobots": mode}))
    wait_settled(fleet, 3)
    first = fleet.revisions()[names[0]]
    offline = names[2]
    # Off the network: its Lease lapses and the node-lifecycle controller marks it Ready=Unknown.
    cluster.set_robot_reachable(offline, False)
    wait_for(
        lambda: fleet.system()["status"]["robots"]["unreachable"] == 1,
        timeout=60,
        message="the robot offline",
    )
    return fleet, names, offline, first


def test_an_offline_robot_is_skipped_and_updated_when_it_returns(
    cluster: Any, namespace: str, operator: Any, robots: Callable[..., list[str]], fleet_label: str
) -> None:
    fleet, names, offline, first = _deploy(cluster, namespace, robots, fleet_label, "Skip")
    fleet.change("2")
    wait_for(lambda: rollout_complete(fleet), timeout=120, message=lambda: f"{fleet.rollout()}")
    revisions = fleet.revisions()
    assert revisions[names[0]] != first and revisions[names[1]] != first
    assert revisions[offline] == first
    rollout = fleet.rollout()
    assert rollout["counts"]["offline"] == 1 and "skipped" in rollout["message"]
    conditions = {c["type"]: c for c in fleet.system()["status"]["conditions"]}
    assert conditions["Ready"]["status"] == "True"  # one robot off the network does not stall the fleet

    cluster.set_robot_reachable(offline, True)
    wait_for(lambda: fleet.revisions()[offline] != first, timeout=120, message="the returning robot updated")
    wait_settled(fleet, 3)


def test_an_offline_robot_is_waited_for_when_the_setting_says_wait(
    cluster: Any, namespace: str, operator: Any, robots: Callable[..., list[str]], fleet_label: str
) -> None:
    fleet, names, offline, first = _deploy(cluster, namespace, robots, fleet_label, "Wait")
    fleet.change("2")
    wait_for(lambda: fleet.rollout().get("waitingFor") == [offline], timeout=60, message="waiting reported")
    holds_for(
        lambda: set(fleet.revisions().values()) == {first}, 6, message="no robot moved while one is offline"
    )
    assert fleet.events("WaitingForOfflineRobots")

    cluster.set_robot_reachable(offline, True)
    wait_settled(fleet, 3)
    assert first not in set(fleet.revisions().values())
