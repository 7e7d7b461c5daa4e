"""Deletion needs no running operator (no finalizers), a system created again under its name keeps
what its robots need, and a tree kept in a ConfigMap is followed."""

from __future__ import annotations

import os
import signal

import pytest
from coral_api import condition, is_current_and_true
from coral_core import names
from coral_operator.planning import naming
from coral_testbed.cluster import controlplane
from coral_testbed.waiting import holds_for
from kubernetes import client as k8s
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
        namespace,
        {"metadata": {"name": "mission", "labels": {names.LABEL_SOURCE: "true"}}, "data": {"tree.xml": tree}},
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


def _leftovers_of(scenario: Scenario, uid: str) -> list[str]:
    """The system's ServiceAccount, Role, RoleBinding, ConfigMaps and ControllerRevisions that
    still name the owner `uid`."""
    api, namespace = scenario.cluster.api_client, scenario.namespace
    core, rbac, apps = k8s.CoreV1Api(api), k8s.RbacAuthorizationV1Api(api), k8s.AppsV1Api(api)
    selector = "coral.dev/system=fleet"
    listed = [
        *core.list_namespaced_service_account(namespace, label_selector=selector).items,
        *rbac.list_namespaced_role(namespace, label_selector=selector).items,
        *rbac.list_namespaced_role_binding(namespace, label_selector=selector).items,
        *core.list_namespaced_config_map(namespace, label_selector=selector).items,
        *apps.list_namespaced_controller_revision(namespace, label_selector=selector).items,
    ]
    return [
        f"{type(item).__name__.removeprefix('V1')}/{item.metadata.name}"
        for item in listed
        if any(ref.uid == uid for ref in item.metadata.owner_references or [])
    ]


def _controller_manager_pid(scenario: Scenario) -> int:
    state = controlplane.load_state(scenario.cluster.state_dir)
    assert state is not None
    return next(p.pid for p in state.processes if p.name == "kube-controller-manager")


def test_a_system_created_again_under_its_name_keeps_what_its_robots_need(scenario: Scenario) -> None:
    """Deleted and created again at once (`kubectl replace --force`, a GitOps tool recreating it),
    a system finds the first one's ServiceAccount, Role, RoleBinding, ConfigMaps and
    ControllerRevisions still there, waiting for the garbage collector. The collector is held back
    (kube-controller-manager stopped for a few seconds), so they are certainly there when the new
    system starts, as on a busy cluster; once it runs, the new system must still have them, and
    pods made after that must still be admitted."""
    if not scenario.cluster.is_local:
        pytest.skip("holds back the garbage collector of the control plane this project starts")
    coral, wait, namespace = scenario.coral, scenario.wait, scenario.namespace
    scenario.robots(1)
    first = scenario.deploy()["metadata"]["uid"]
    assert _leftovers_of(scenario, first)

    manager = _controller_manager_pid(scenario)
    os.kill(manager, signal.SIGSTOP)
    try:
        coral.delete_system("fleet")
        wait(lambda: coral.system("fleet") is None, "the first system to be deleted")
        # What the collector happened to remove first on the cluster where this was seen: the
        # robots' instances and pods.
        for name in coral.instances():
            coral.custom.delete_namespaced_custom_object(
                "coral.dev", "v1alpha1", namespace, "coralinstances", name
            )
        for name in coral.pods():
            coral.core.delete_namespaced_pod(name, namespace)
        wait(lambda: not coral.instances() and not coral.pods(), "the first system's robots to be gone")
        second = coral.create_system(scenario.mission())["metadata"]["uid"]
        wait(lambda: coral.instances(), "the new system's instance")
    finally:
        os.kill(manager, signal.SIGCONT)
    wait(lambda: not _leftovers_of(scenario, first), "the garbage collector to finish with the first system")

    account = naming.executor_account_name("fleet")
    owned = _leftovers_of(scenario, second)
    for kind in ("ServiceAccount", "Role", "RoleBinding"):
        assert f"{kind}/{account}" in owned, owned
    wanted = {
        config_map
        for instance in coral.instances().values()
        for config_map in (instance["spec"]["tree"]["configMap"], instance["spec"]["parameters"]["configMap"])
    }
    assert wanted <= set(coral.config_maps())

    system = wait(
        lambda: (s := coral.system("fleet")) and is_current_and_true(s, "Ready") and s,
        "the new system to become Ready",
    )
    skillset = system["spec"]["skillsets"][0]
    env = [*skillset.get("env", []), {"name": "MODE", "value": "changed"}]
    coral.patch_system("fleet", {"spec": {"skillsets": [{**skillset, "env": env}]}})
    wait(
        lambda: (
            (s := coral.system("fleet"))
            and is_current_and_true(s, "Ready")
            and s["status"].get("revision") != system["status"]["revision"]
            and s["status"]["robots"]["updated"] == 1
        ),
        "the robot's new pods to be admitted and the update to complete",
        timeout=60,
    )
