"""`layout: PodPerRobot` on kwok robots: one pod per robot, the same CoralInstance status as the
default layout, and a namespace enforcing Pod Security `baseline` accepts it.

kwok marks pods and their containers Running and Ready without running anything, so these tests
carry the operator's side (the pod it builds, how it reads the pod back, the status); the kubelet's
side (start order, probes, a crashing container) is in tests/integration/kind, on kind robots.
"""

from __future__ import annotations

from typing import Any

import pytest
from coral_api import Coral, condition, fleet_mission, is_current_and_true
from kubernetes import client as k8s
from kubernetes.client.exceptions import ApiException
from scenarios import Scenario

pytestmark = [pytest.mark.cluster, pytest.mark.slow]

# Conditions whose reason and status must match across layouts (messages name pods and revisions).
COMPARED = ("Ready", "Reconciling", "Stalled", "RobotReachable", "ComponentsReady", "LibraryDegraded")


def _mission(name: str, robot_label: str, layout: str, network: str = "Host") -> dict[str, Any]:
    manifest = fleet_mission(name, robot_label)
    manifest["spec"]["layout"] = layout
    manifest["spec"]["ros"] = {**manifest["spec"].get("ros", {}), "network": network}
    return manifest


def _summary(instance: dict[str, Any]) -> dict[str, Any]:
    status = instance["status"]
    return {
        "conditions": {
            c["type"]: (c["status"], c["reason"]) for c in status["conditions"] if c["type"] in COMPARED
        },
        "components": [(c["name"], c["role"], c["ready"], c["phase"]) for c in status["components"]],
        "robot": status["robot"]["reachable"],
    }


def _ready_instance(coral: Coral, system: str) -> dict[str, Any] | None:
    for instance in coral.instances().values():
        if instance["spec"]["system"] == system and is_current_and_true(instance, "Ready"):
            return instance
    return None


def _conditions_of(coral: Coral) -> dict[str, list[tuple[str, str, str, str]]]:
    """Each instance's conditions, for a timeout message that says where a robot got stuck."""
    return {
        name: [
            (c["type"], c["status"], c.get("reason", ""), c.get("message", ""))
            for c in (instance.get("status") or {}).get("conditions") or []
        ]
        for name, instance in coral.instances().items()
    }


def test_one_pod_per_robot_reads_like_one_pod_per_component(scenario: Scenario) -> None:
    coral, wait, fleet_label = scenario.coral, scenario.wait, scenario.fleet_label
    scenario.make_robots(1, {"fleet": f"{fleet_label}-c"}, start=1)
    scenario.make_robots(1, {"fleet": f"{fleet_label}-r"}, start=2)
    coral.create_system(_mission("per-component", f"{fleet_label}-c", "PodPerComponent"))
    coral.create_system(_mission("per-robot", f"{fleet_label}-r", "PodPerRobot"))
    per_component = wait(lambda: _ready_instance(coral, "per-component"), "the PodPerComponent robot Ready")
    per_robot = wait(lambda: _ready_instance(coral, "per-robot"), "the PodPerRobot robot Ready")
    assert _summary(per_robot) == _summary(per_component)

    pods = [p for p in coral.pods().values() if p.metadata.labels.get("coral.dev/system") == "per-robot"]
    assert len(pods) == 1, [p.metadata.name for p in pods]
    (pod,) = pods
    assert [(c.name, c.restart_policy) for c in pod.spec.init_containers] == [
        ("lidar-driver", "Always"),
        ("slam", "Always"),
    ]
    assert [c.name for c in pod.spec.containers] == ["executor"]
    assert {c["pod"] for c in per_robot["status"]["components"]} == {pod.metadata.name}
    assert all(v.host_path is None for v in pod.spec.volumes if v.name == "plugins")


def _enforce_baseline(cluster: Any, namespace: str) -> None:
    k8s.CoreV1Api(cluster.api_client).patch_namespace(
        namespace, {"metadata": {"labels": {"pod-security.kubernetes.io/enforce": "baseline"}}}
    )


def test_a_baseline_namespace_accepts_one_pod_per_robot_and_says_why_it_refuses_the_other(
    scenario: Scenario,
) -> None:
    coral, wait = scenario.coral, scenario.wait
    _enforce_baseline(scenario.cluster, scenario.namespace)
    scenario.robots(1)
    manifest = _mission("baseline", scenario.fleet_label, "PodPerRobot", network="Pod")
    for role in ("drivers", "skillsets", "executors"):
        for component in manifest["spec"].get(role, []):
            component.pop("hostPaths", None)  # baseline refuses every hostPath volume
    coral.create_system(manifest)
    ready = wait(
        lambda: _ready_instance(coral, "baseline"),
        lambda: f"the PodPerRobot robot Ready under baseline; instances: {_conditions_of(coral)}",
    )
    assert condition(ready, "Stalled")["status"] == "False"

    # Changing the layout on a live system is a revision like any other: the robot moves to it, and
    # baseline refuses the per-component pods (they mount the robot's plugin folder by hostPath).
    coral.patch_system("baseline", {"spec": {"layout": "PodPerComponent"}})

    def refused() -> dict[str, Any] | None:
        for instance in coral.instances().values():
            stalled = condition(instance, "Stalled")
            if stalled.get("status") == "True" and stalled.get("reason") == "PodRefused":
                return instance
        return None

    instance = wait(refused, "the PodPerComponent pods refused with a reason on the instance")
    message = condition(instance, "Ready")["message"]
    assert "PodSecurity" in message and "baseline" in message and "hostPath" in message, message
    assert instance["spec"]["layout"] == "PodPerComponent"
    system = wait(
        lambda: (s := coral.system("baseline")) and condition(s, "Ready").get("status") == "False" and s,
        "the system to summarise the refusal",
    )
    assert condition(system, "Ready")["message"], "the system's Ready condition says nothing"


def test_an_image_only_change_keeps_the_robot_pod_and_any_other_change_replaces_it(
    scenario: Scenario,
) -> None:
    coral, wait = scenario.coral, scenario.wait
    scenario.robots(1)
    manifest = _mission("images", scenario.fleet_label, "PodPerRobot")
    coral.create_system(manifest)
    first = wait(lambda: _ready_instance(coral, "images"), "the robot Ready")
    (pod,) = coral.pods().values()

    skillsets = manifest["spec"]["skillsets"]
    skillsets[0]["image"] = "coral/slam-skillset:0.2.0"
    coral.patch_system("images", {"spec": {"skillsets": skillsets}})

    def moved(previous: dict[str, Any]) -> dict[str, Any] | None:
        instance = _ready_instance(coral, "images")
        if instance is None or instance["spec"]["revision"] == previous["spec"]["revision"]:
            return None
        return instance if instance["status"].get("revision") == instance["spec"]["revision"] else None

    second = wait(lambda: moved(first), "the robot on the image-only revision")
    (patched,) = coral.pods().values()
    assert patched.metadata.uid == pod.metadata.uid, "an image-only change replaced the pod"
    slam = next(c for c in patched.spec.init_containers if c.name == "slam")
    assert slam.image == "coral/slam-skillset:0.2.0"
    assert patched.metadata.labels["coral.dev/revision"] == second["spec"]["revision"]

    skillsets[0]["env"] = [{"name": "SLAM_MODE", "value": "fast"}]
    coral.patch_system("images", {"spec": {"skillsets": skillsets}})
    wait(lambda: moved(second), "the robot on the revision with a new environment")
    replaced = wait(
        lambda: [
            p
            for p in coral.pods().values()
            if p.metadata.deletion_timestamp is None and p.metadata.uid != pod.metadata.uid
        ],
        "a new robot pod",
    )
    assert len(replaced) == 1
    assert all(
        p.metadata.uid != pod.metadata.uid
        for p in coral.pods().values()
        if p.metadata.deletion_timestamp is None
    )


def test_proceed_on_timeout_with_one_pod_per_robot_is_refused_at_admission(
    cluster: Any, namespace: str, coral_crds: None, fleet_label: str
) -> None:
    manifest = _mission("proceed", fleet_label, "PodPerRobot")
    manifest["spec"]["startup"] = {"onTimeout": "Proceed"}
    with pytest.raises(ApiException) as refused:
        Coral(cluster.api_client, namespace).create_system(manifest)
    assert refused.value.status == 422
    assert "spec.startup.onTimeout" in refused.value.body
    assert "onTimeout Proceed needs layout PodPerComponent" in refused.value.body
