"""CoralSystems written to hurt: each ends in a clear status or an admission refusal within a minute,
while the operator (in a memory cgroup of the chart's limit, as in its pod) stays up, is never
OOM-killed, logs no traceback, and keeps serving a healthy system in another namespace.

One operator serves three namespaces for the whole module: `hostile` (the attacks), `healthy` (a
system that must stay Ready with the same pods throughout) and `baseline` (labelled for Pod
Security's baseline level, which refuses Coral's pods). The policy is the shipped default, opened
only for the host network and the robot's bags, as an administrator running the fleet example would.
"""

from __future__ import annotations

import copy
import socket
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

import pytest
from coral_api import condition, executor_client, fleet_mission, is_current_and_true
from coral_testbed.waiting import holds_for, wait_for, wait_until_steady
from fixtures.cluster import create_test_namespace
from hostile import CLEAR_WITHIN_S, NEEDS_A_MEMORY_CGROUP, HostileStage, forge_ready, refused_at_admission
from kubernetes import client as k8s

pytestmark = [pytest.mark.cluster, pytest.mark.slow, NEEDS_A_MEMORY_CGROUP]

HEAD = '<root BTCPP_format="4" main_tree_to_execute="Main">\n'
SUBTREE_MAIN = '  <BehaviorTree ID="Main">\n    <SubTree ID="Nav"/>\n  </BehaviorTree>\n'


@dataclass
class Stage(HostileStage):
    hostile: str
    baseline: str


@pytest.fixture(scope="module")
def stage(cluster: Any, coral_crds: None, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Stage]:
    core = k8s.CoreV1Api(cluster.api_client)
    baseline_labels = {"pod-security.kubernetes.io/enforce": "baseline"}
    namespaces = [
        create_test_namespace(core, "hostile"),
        create_test_namespace(core, "healthy"),
        create_test_namespace(core, "baseline", baseline_labels),
    ]
    hostile, healthy, baseline = namespaces
    log = tmp_path_factory.mktemp("hostile") / "operator.log"
    with Stage.serving(cluster, namespaces, healthy, log, hostile=hostile, baseline=baseline) as stage:
        yield stage


def _attack(stage: Stage, name: str, change: Callable[[dict[str, Any]], None]) -> dict[str, str]:
    """Create the system in the hostile namespace; its Stalled condition once it is clear."""
    manifest = copy.deepcopy(fleet_mission(name, stage.fleet))
    change(manifest["spec"])
    stage.coral(stage.hostile).create_system(manifest)
    return stage.stalled(stage.hostile, name)


def _tree(text: str) -> Callable[[dict[str, Any]], None]:
    def change(spec: dict[str, Any]) -> None:
        spec["tree"] = {"inline": text}

    return change


def _including(path: str) -> Callable[[dict[str, Any]], None]:
    return _tree(f'{HEAD}  <include path="{path}"/>\n{SUBTREE_MAIN}</root>\n')


def _driver(**fields: Any) -> Callable[[dict[str, Any]], None]:
    def change(spec: dict[str, Any]) -> None:
        spec["drivers"][0].update(fields)

    return change


def test_an_include_of_dev_zero_is_refused_without_reading_it(stage: Stage) -> None:
    stalled = _attack(stage, "zero", _including("/dev/zero"))
    assert stalled["reason"] == "InvalidTree"
    assert (
        "coralsystem/zero spec.tree.inline:2: <include path='/dev/zero'> names no file of this CoralSystem"
        in (stalled["message"])
    )
    stage.assert_still_serving()


def test_an_include_of_a_host_file_reveals_nothing_about_it(stage: Stage) -> None:
    host = _attack(stage, "hostname", _including("/etc/hostname"))
    missing = _attack(stage, "missing", _including("/etc/no-such-file"))
    # The same words whether the host has such a file or not.
    assert host["message"].replace("hostname", "X") == missing["message"].replace("missing", "X").replace(
        "no-such-file", "X"
    )
    assert socket.gethostname() not in host["message"]
    stage.assert_still_serving()


def test_a_tree_700_deep_is_refused_with_its_depth(stage: Stage) -> None:
    body = "<Inverter>" * 700 + "<AlwaysSuccess/>" + "</Inverter>" * 700
    stalled = _attack(stage, "deep", _tree(f'{HEAD}<BehaviorTree ID="Main">{body}</BehaviorTree></root>'))
    assert stalled["reason"] == "InvalidTree"
    assert "spec.tree.inline:2: elements nest 703 levels deep; the limit is 128" in stalled["message"]
    stage.assert_still_serving()


def test_billion_laughs_is_refused(stage: Stage) -> None:
    entities = '<!ENTITY a "lol">' + "".join(
        f'<!ENTITY {chr(98 + i)} "{("&" + chr(97 + i) + ";") * 10}">' for i in range(9)
    )
    text = f'<?xml version="1.0"?>\n<!DOCTYPE root [{entities}]>\n{HEAD}{SUBTREE_MAIN}<x v="&j;"/></root>\n'
    stalled = _attack(stage, "laughs", _tree(text))
    assert "spec.tree.inline:2: entity declarations are not allowed (<!ENTITY a>)" in stalled["message"]
    stage.assert_still_serving()


def test_a_tree_with_thousands_of_errors_is_summarised(stage: Stage) -> None:
    sleeps = "<Sleep/>" * 5000
    stalled = _attack(
        stage,
        "errors",
        _tree(f'{HEAD}<BehaviorTree ID="Main"><Sequence>{sleeps}</Sequence></BehaviorTree></root>'),
    )
    assert "<Sleep> needs the port [msec]; it has no default" in stalled["message"]
    assert stalled["message"].endswith("; and 4980 more problems")
    stage.assert_still_serving()


def test_a_tree_of_almost_a_megabyte_is_refused_at_admission_naming_the_field(stage: Stage) -> None:
    padding = "<!--" + "x" * 990_000 + "-->"
    manifest = fleet_mission("huge", stage.fleet)
    manifest["spec"]["tree"] = {"inline": f"{HEAD}{padding}{SUBTREE_MAIN}</root>"}
    message = refused_at_admission(stage.coral(stage.hostile), manifest)
    assert "spec.tree.inline: Too long: may not be more than 262144 bytes" in message
    stage.assert_still_serving()


def test_a_privileged_driver_is_refused_by_the_default_policy(stage: Stage) -> None:
    stalled = _attack(stage, "privileged", _driver(privileged=True))
    assert stalled["reason"] == "PolicyDenied"
    assert (
        f"spec.drivers[0] (lidar-driver): privileged is not allowed in namespace {stage.hostile}"
        in (stalled["message"])
    )
    stage.assert_still_serving()


def test_a_host_path_of_the_root_folder_is_refused(stage: Stage) -> None:
    stalled = _attack(
        stage, "rootfs", _driver(hostPaths=[{"hostPath": "/", "mountPath": "/host", "readOnly": False}])
    )
    assert (
        f"hostPaths[0].hostPath: host path / is outside the folders namespace {stage.hostile} may mount "
        f"(/var/lib/coral/data/{stage.hostile}, /var/lib/coral/bags)" in (stalled["message"])
    )
    stage.assert_still_serving()


def test_run_as_root_is_refused(stage: Stage) -> None:
    stalled = _attack(stage, "root", _driver(runAsRoot=True))
    assert (
        f"spec.drivers[0] (lidar-driver): runAsRoot is not allowed in namespace {stage.hostile}"
        in (stalled["message"])
    )
    stage.assert_still_serving()


def test_a_plugin_root_of_etc_is_refused(stage: Stage) -> None:
    def plugins_in_etc(spec: dict[str, Any]) -> None:
        spec["plugins"] = {"hostPathRoot": "/etc"}

    stalled = _attack(stage, "etc", plugins_in_etc)
    assert (
        "spec.plugins.hostPathRoot: /etc is not an allowed plugin root (/var/lib/coral/plugins)"
        in (stalled["message"])
    )
    stage.assert_still_serving()


def test_a_dot_dot_path_is_compared_after_normalising(stage: Stage) -> None:
    climbing = [
        {"hostPath": f"/var/lib/coral/data/{stage.hostile}/../../../../../etc", "mountPath": "/etc-of-robot"}
    ]
    stalled = _attack(stage, "climb", _driver(hostPaths=climbing))
    assert f"host path /etc is outside the folders namespace {stage.hostile} may mount" in stalled["message"]
    stage.assert_still_serving()


def _baseline_instance(stage: Stage) -> dict[str, Any]:
    coral = stage.coral(stage.baseline)
    if coral.system("psa") is None:
        coral.create_system(fleet_mission("psa", stage.fleet))

    def refused() -> dict[str, Any] | None:
        for instance in coral.instances().values():
            ready = condition(instance, "ComponentsReady")
            if ready.get("reason") == "PodRefused" and condition(instance, "Stalled").get("status") == "True":
                return instance
        return None

    return wait_for(
        refused,
        timeout=CLEAR_WITHIN_S,
        interval=0.3,
        message=lambda: f"the instance to report its refused pod; operator log:\n{stage.logs()[-3000:]}",
    )


def test_a_pod_refused_by_pod_security_admission_is_reported_with_the_servers_message(stage: Stage) -> None:
    instance = _baseline_instance(stage)
    message = condition(instance, "Stalled")["message"]
    assert "The API server refused the pod of lidar-driver:" in message
    assert 'violates PodSecurity "baseline:latest"' in message and "hostPath volumes" in message
    assert condition(instance, "Ready")["status"] == "False"
    core = k8s.CoreV1Api(stage.cluster.api_client)
    name = instance["metadata"]["name"]

    def event() -> bool:
        events = core.list_namespaced_event(
            stage.baseline, field_selector=f"involvedObject.name={name}"
        ).items
        return any(e.reason == "PodRefused" and "PodSecurity" in (e.message or "") for e in events)

    wait_for(event, timeout=CLEAR_WITHIN_S, message="a PodRefused Event on the instance")
    stage.assert_still_serving()


def test_a_forged_ready_condition_is_overwritten(stage: Stage) -> None:
    instance = _baseline_instance(stage)
    name = instance["metadata"]["name"]
    custom = k8s.CustomObjectsApi(stage.cluster.api_client)
    forge_ready(custom, instance, "Ready")

    def corrected() -> bool:
        current = custom.get_namespaced_custom_object(
            "coral.dev", "v1alpha1", stage.baseline, "coralinstances", name
        )
        ready = condition(current, "Ready")
        return ready.get("status") == "False" and ready.get("reason") == "PodRefused"

    wait_for(corrected, timeout=CLEAR_WITHIN_S, interval=0.3, message="the forged Ready to be overwritten")
    stage.assert_still_serving()


def test_settled_statuses_are_not_rewritten(stage: Stage) -> None:
    """Overwriting forged fields must not turn into rewriting the operator's own ones forever."""
    _baseline_instance(stage)
    custom = k8s.CustomObjectsApi(stage.cluster.api_client)

    def versions() -> dict[str, str]:
        seen = {}
        for namespace in (stage.healthy, stage.baseline):
            items = custom.list_namespaced_custom_object("coral.dev", "v1alpha1", namespace, "coralinstances")
            seen |= {i["metadata"]["name"]: i["metadata"]["resourceVersion"] for i in items["items"]}
        return seen

    before = versions()
    holds_for(lambda: versions() == before, duration=6, message="instance statuses left alone once settled")
    stage.assert_still_serving()


def test_a_condition_forged_with_the_executors_own_identity_is_overwritten(stage: Stage) -> None:
    coral = stage.coral(stage.healthy)
    (name,) = [n for n, i in coral.instances().items() if i["spec"]["system"] == "healthy"]
    as_executor = k8s.CustomObjectsApi(executor_client(stage.cluster, stage.healthy, name))
    instance = coral.instances()[name]
    forged = [
        {**entry, "reason": "Forged", "message": "forged by the executor", "observedGeneration": 999}
        for entry in instance["status"]["conditions"]
        if entry["type"] == "Ready"
    ]
    as_executor.patch_namespaced_custom_object_status(
        "coral.dev",
        "v1alpha1",
        stage.healthy,
        "coralinstances",
        name,
        {"status": {"conditions": forged, "observedGeneration": 999}},
        _content_type="application/merge-patch+json",
    )

    def restored() -> bool:
        current = coral.instances()[name]
        ready = condition(current, "Ready")
        generation = current["metadata"]["generation"]
        return (
            ready.get("reason") == "Ready"
            and ready.get("observedGeneration") == generation
            and current["status"].get("observedGeneration") == generation
            and {c["type"] for c in current["status"]["conditions"]} > {"Ready", "Stalled", "Reconciling"}
        )

    wait_for(restored, timeout=CLEAR_WITHIN_S, interval=0.3, message="the operator's conditions restored")
    # The forged generation makes this robot look out of date to its own system for a moment, and
    # the system may only see that after the instance is restored: Ready is judged once it settles.
    wait_until_steady(
        lambda: is_current_and_true(coral.system("healthy"), "Ready"),
        steady_for=5,
        timeout=CLEAR_WITHIN_S,
        interval=0.3,
        message="the healthy system Ready again",
    )
    stage.assert_still_serving()
