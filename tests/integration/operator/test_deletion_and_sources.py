"""Deletion needs no running operator (no finalizers), and a tree kept in a ConfigMap is followed."""

from __future__ import annotations

import pytest
from coral_api import condition, is_current_and_true
from coral_testbed.waiting import holds_for
from scenarios import Scenario

pytestmark = [pytest.mark.cluster, pytest.mark.slow]


def test_a_system_is_deleted_even_while_the_operator_is_down(scenario: Scenario) -> None:
    coral, wait = scenario.coral, scenario.wait
    scenario.robots(2)
    scenario.deploy()
    assert not coral.system("fleet")["metadata"].get("finalizers")
    assert all(not i["metadata"].get("finalizers") for i in coral.instances().values())

    scenario.operator.stop()
    coral.delete_system("fleet")
    wait(
        lambda: coral.system("fleet") is None and not coral.instances() and not coral.pods(),
        "garbage collection to remove the system, its instances and pods without the operator",
    )


def test_a_tree_from_a_config_map_is_followed_and_a_broken_edit_is_refused(scenario: Scenario) -> None:
    coral, wait, namespace = scenario.coral, scenario.wait, scenario.namespace
    scenario.robots(1)
    mission = scenario.mission()
    tree = mission["spec"]["tree"].pop("inline")
    coral.core.create_namespaced_config_map(
        namespace, {"metadata": {"name": "mission"}, "data": {"tree.xml": tree}}
    )
    mission["spec"]["tree"]["configMapRef"] = {"name": "mission", "key": "tree.xml"}
    first = scenario.deploy(mission)["status"]["revision"]

    edited = tree.replace('msec="500"', 'msec="250"')
    coral.core.patch_namespaced_config_map("mission", namespace, {"data": {"tree.xml": edited}})
    wait(
        lambda: (
            coral.system("fleet")["status"].get("revision") not in (None, first)
            and is_current_and_true(coral.system("fleet"), "Ready")
        ),
        "the edited tree to become a new revision that is Ready",
    )
    executor = next(
        p
        for p in coral.pods().values()
        if p.metadata.labels["coral.dev/role"] == "executor" and p.metadata.deletion_timestamp is None
    )
    tree_maps = [s.config_map.name for s in executor.spec.volumes[1].projected.sources]
    stored = coral.core.read_namespaced_config_map(tree_maps[-1], namespace).data["tree.xml"]
    assert 'msec="250"' in stored

    running = {n: p.metadata.uid for n, p in coral.pods().items()}
    coral.core.patch_namespaced_config_map(
        "mission", namespace, {"data": {"tree.xml": "<root>\n<BehaviorTree>\n"}}
    )
    wait(
        lambda: condition(coral.system("fleet"), "Stalled").get("status") == "True",
        "the broken edit to stall",
    )
    assert "configmap/mission/tree.xml:3:" in condition(coral.system("fleet"), "Stalled")["message"]
    holds_for(
        lambda: {n: p.metadata.uid for n, p in coral.pods().items()} == running,
        duration=3,
        message="the robot keeping what it ran",
    )
