"""Issue 47, item 9, against a real API server and the operator process: a tree made of newlines
costs no time, a ConfigMap its owners did not share is never copied into a system's pods, a
ConfigMap name the API server cannot take is refused at admission, and names chosen to collide
with another system's neither starve nor hijack it. Throughout, a healthy system keeps being
served and the operator logs no traceback.
"""

from __future__ import annotations

import uuid
from typing import Any

import psutil
import pytest
from coral_api import condition, is_current_and_true
from coral_core import names
from coral_operator.planning import naming
from coral_testbed.waiting import holds_for
from kubernetes import client as k8s
from kubernetes.client.exceptions import ApiException
from scenarios import Scenario

pytestmark = [pytest.mark.cluster, pytest.mark.slow]

TREE = (
    '<root BTCPP_format="4" main_tree_to_execute="Patrol">\n'
    '  <BehaviorTree ID="Patrol">\n'
    "    <Sequence>{run}<AlwaysSuccess/></Sequence>\n"
    "  </BehaviorTree>\n"
    "</root>\n"
)


def _stalled(scenario: Scenario, name: str, reason: str) -> dict[str, Any] | None:
    found = condition(scenario.coral.system(name), "Stalled")
    return found if found.get("status") == "True" and found.get("reason") == reason else None


def _serving(scenario: Scenario) -> None:
    assert is_current_and_true(scenario.coral.system("healthy"), "Ready")
    assert "Traceback" not in scenario.operator.logs(), scenario.operator.logs()[-4000:]


def test_a_tree_made_of_newlines_costs_the_operator_little_cpu(scenario: Scenario) -> None:
    """The element's text grew a line at a time by copying it: 11-15 s of CPU per pass for a tree of
    768 KiB. Trees are now at most 256 KiB from any source: on this one the quadratic parser spent
    0.9 s of CPU per validation, the linear one 0.02 s, and the whole pass about 0.1 s. The
    operator's own CPU time is measured, not the wall clock, so a busy machine cannot fail it."""
    scenario.robots(1)
    scenario.deploy(scenario.mission("healthy"))
    # The largest tree the operator reads, nearly all newlines.
    text = TREE.format(run="\n" * 260_000)
    scenario.coral.core.create_namespaced_config_map(
        scenario.namespace,
        {"metadata": {"name": "lines", "labels": {names.LABEL_SOURCE: "true"}}, "data": {"tree.xml": text}},
    )
    mission = scenario.mission("lines")
    mission["spec"]["tree"] = {"configMapRef": {"name": "lines", "key": "tree.xml"}, "tickRateHz": 10.0}
    assert scenario.operator.process is not None
    operator = psutil.Process(scenario.operator.process.pid)
    before = sum(operator.cpu_times()[:2])
    scenario.coral.create_system(mission)
    scenario.wait(
        lambda: (scenario.coral.system("lines") or {}).get("status", {}).get("revision"),
        "the tree of newlines to be validated into a revision",
    )
    spent = sum(operator.cpu_times()[:2]) - before
    assert spent < 0.5, f"the operator spent {spent:.1f} s of CPU on the system"
    scenario.wait(lambda: is_current_and_true(scenario.coral.system("lines"), "Ready"), "the system Ready")
    _serving(scenario)


def test_a_config_map_its_owners_did_not_mark_is_never_copied_into_a_systems_pods(
    scenario: Scenario,
) -> None:
    """A user who may write CoralSystems but not read ConfigMaps had the operator copy one into
    their own pods (a confused deputy)."""
    scenario.robots(1)
    scenario.deploy(scenario.mission("healthy"))
    core, namespace = scenario.coral.core, scenario.namespace
    secret = "<!-- billing password: hunter2 -->"
    tree = TREE.format(run=secret)
    core.create_namespaced_config_map(
        namespace, {"metadata": {"name": "billing"}, "data": {"tree.xml": tree}}
    )
    mission = scenario.mission("deputy")
    mission["spec"]["tree"] = {"configMapRef": {"name": "billing", "key": "tree.xml"}, "tickRateHz": 10.0}
    scenario.coral.create_system(mission)
    stalled = scenario.wait(
        lambda: _stalled(scenario, "deputy", "ConfigMapNotASource"), "the system Stalled, not a source"
    )
    assert "spec.tree.configMapRef" in stalled["message"] and names.LABEL_SOURCE in stalled["message"]

    def copied() -> bool:
        maps = core.list_namespaced_config_map(namespace).items
        return any(secret in (m.data or {}).get("tree.xml", "") for m in maps if m.metadata.name != "billing")

    holds_for(
        lambda: not copied() and not _instances_of(scenario, "deputy"), duration=5, message="nothing copied"
    )
    # Its owners' label is their consent: then the same system is served.
    core.patch_namespaced_config_map(
        "billing", namespace, {"metadata": {"labels": {names.LABEL_SOURCE: "true"}}}
    )
    scenario.wait(lambda: is_current_and_true(scenario.coral.system("deputy"), "Ready"), "the system served")
    _serving(scenario)


def test_a_config_map_name_the_api_server_cannot_take_is_refused_at_admission(scenario: Scenario) -> None:
    """A name with `%` got a 400 on every read, retried forever with a traceback and no status."""
    mission = scenario.mission("percent")
    mission["spec"]["parameters"] = {"configMapRef": {"name": "params%2fx", "key": "params.yaml"}}
    with pytest.raises(ApiException) as refused:
        scenario.coral.create_system(mission)
    assert refused.value.status == 422
    assert "spec.parameters.configMapRef.name" in (refused.value.body or "")


def _instances_of(scenario: Scenario, system: str) -> list[str]:
    return [name for name, i in scenario.coral.instances().items() if i["spec"]["system"] == system]


def test_systems_whose_names_join_alike_each_get_their_own_instance(scenario: Scenario) -> None:
    """ "a" + "b-c" and "a-b" + "c" were one CoralInstance: the second system was never served."""
    tag = uuid.uuid4().hex[:5]
    first_robot, second_robot = f"n{tag}-z{tag}", f"z{tag}"
    scenario.cluster.add_robots([first_robot], {"fleet": f"{scenario.fleet_label}-1"})
    scenario.cluster.add_robots([second_robot], {"fleet": f"{scenario.fleet_label}-2"})
    try:
        first, second = scenario.mission(f"s{tag}"), scenario.mission(f"s{tag}-n{tag}")
        first["spec"]["robots"] = {"matchLabels": {"fleet": f"{scenario.fleet_label}-1"}}
        second["spec"]["robots"] = {"matchLabels": {"fleet": f"{scenario.fleet_label}-2"}}
        assert f"{first['metadata']['name']}-{first_robot}" == f"{second['metadata']['name']}-{second_robot}"
        scenario.deploy(first)
        scenario.deploy(second)
        (mine,), (theirs,) = _instances_of(scenario, f"s{tag}"), _instances_of(scenario, f"s{tag}-n{tag}")
        assert mine != theirs
        assert scenario.coral.instances()[theirs]["spec"]["robot"] == second_robot
    finally:
        scenario.cluster.remove_robots([first_robot, second_robot])


def test_a_system_named_like_anothers_shortened_name_shares_nothing_with_it(scenario: Scenario) -> None:
    """A system named exactly like another's shortened label shared its executor ServiceAccount,
    and deleting it deleted the other's."""
    scenario.robots(1)
    victim = "v" + uuid.uuid4().hex * 3  # 97 characters: its label and account name are shortened
    shortened = naming.label_value(victim)
    assert len(shortened) <= 63
    scenario.deploy(scenario.mission(victim))
    scenario.deploy(scenario.mission(shortened))
    accounts = {naming.executor_account_name(victim), naming.executor_account_name(shortened)}
    assert len(accounts) == 2
    core = k8s.CoreV1Api(scenario.cluster.api_client)
    for account in accounts:
        owners = core.read_namespaced_service_account(account, scenario.namespace).metadata.owner_references
        assert len(owners) == 1
    scenario.coral.delete_system(shortened)
    scenario.wait(lambda: not _instances_of(scenario, shortened), "the impostor's instances to go")
    kept = core.read_namespaced_service_account(naming.executor_account_name(victim), scenario.namespace)
    assert [o.name for o in kept.metadata.owner_references] == [victim]
    holds_for(
        lambda: is_current_and_true(scenario.coral.system(victim), "Ready"),
        duration=5,
        message="victim Ready",
    )
    assert "Traceback" not in scenario.operator.logs(), scenario.operator.logs()[-4000:]


def test_an_account_made_by_hand_under_a_systems_name_is_reported_not_used(scenario: Scenario) -> None:
    """Another owner's object under a system's name was silently taken (or relied on)."""
    scenario.robots(1)
    scenario.deploy(scenario.mission("healthy"))
    core = k8s.CoreV1Api(scenario.cluster.api_client)
    account = naming.executor_account_name("squatted")
    core.create_namespaced_service_account(scenario.namespace, {"metadata": {"name": account}})
    scenario.coral.create_system(scenario.mission("squatted"))
    stalled = scenario.wait(
        lambda: _stalled(scenario, "squatted", "NameTaken"), "the system Stalled, name taken"
    )
    assert f"ServiceAccount {account}" in stalled["message"] and "no owner" in stalled["message"]
    assert not _instances_of(scenario, "squatted")
    assert not core.read_namespaced_service_account(account, scenario.namespace).metadata.owner_references
    _serving(scenario)
