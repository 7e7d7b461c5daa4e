"""Rollouts act on CoralInstances, so `layout: PodPerRobot` rolls out as the default layout does: a
robot whose tree is RUNNING keeps its one pod until the tree ends, an offline robot is skipped."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest
from coral_testbed.waiting import holds_for, wait_for
from fleet import Fleet, mission, rollout_complete, wait_settled

pytestmark = [pytest.mark.cluster, pytest.mark.slow]


def _robot_pods(fleet: Fleet, robot: str) -> list[str]:
    pods = fleet.core.list_namespaced_pod(fleet.namespace, label_selector=f"coral.dev/robot={robot}").items
    return sorted(p.metadata.uid for p in pods if p.metadata.deletion_timestamp is None)


def _one_pod_mission(fleet_label: str, rollout: dict[str, Any]) -> dict[str, Any]:
    manifest = mission("patrol", fleet_label, rollout)
    manifest["spec"]["layout"] = "PodPerRobot"
    return manifest


def test_a_robot_in_mission_keeps_its_one_pod_until_its_tree_finishes(
    cluster: Any, namespace: str, operator: Any, robots: Callable[..., list[str]], fleet_label: str
) -> None:
    busy, idle = robots(2, {"fleet": fleet_label})
    fleet = Fleet(cluster.api_client, namespace, "patrol")
    fleet.create(_one_pod_mission(fleet_label, {"maxUnavailable": "100%"}))
    wait_settled(fleet, 2)
    first = fleet.revisions()[busy]
    (pod,) = _robot_pods(fleet, busy)
    fleet.set_tree(busy, "RUNNING")
    wait_for(lambda: fleet.system()["status"]["trees"]["running"] == 1, timeout=60, message="RUNNING counted")

    fleet.change("2")
    wait_for(lambda: fleet.revisions()[idle] != first, timeout=90, message="the idle robot moved")
    wait_for(lambda: fleet.rollout().get("waitingFor") == [busy], timeout=60, message="the lock reported")
    holds_for(
        lambda: fleet.revisions()[busy] == first and _robot_pods(fleet, busy) == [pod],
        6,
        message="the robot in mission untouched",
    )

    fleet.set_tree(busy, "SUCCESS")
    wait_settled(fleet, 2)
    assert fleet.revisions()[busy] != first
    (replaced,) = _robot_pods(fleet, busy)
    assert replaced != pod  # an environment change replaces the whole pod in this layout


def test_an_offline_robot_is_skipped(
    cluster: Any, namespace: str, operator: Any, robots: Callable[..., list[str]], fleet_label: str
) -> None:
    names = robots(3, {"fleet": fleet_label})
    fleet = Fleet(cluster.api_client, namespace, "patrol")
    fleet.create(_one_pod_mission(fleet_label, {"maxUnavailable": 1, "offlineRobots": "Skip"}))
    wait_settled(fleet, 3)
    first = fleet.revisions()[names[0]]
    offline = names[2]
    # Off the network: its Lease lapses and the node-lifecycle controller marks it Ready=Unknown.
    cluster.set_robot_reachable(offline, False)
    wait_for(lambda: fleet.system()["status"]["robots"]["unreachable"] == 1, timeout=60, message="offline")
    fleet.change("2")
    wait_for(lambda: rollout_complete(fleet), timeout=120, message=lambda: f"{fleet.rollout()}")
    revisions = fleet.revisions()
    assert revisions[names[0]] != first and revisions[names[1]] != first and revisions[offline] == first
    assert fleet.rollout()["counts"]["offline"] == 1
