"""The same CoralSystem planned as one pod per component and as one pod per robot.

`PodPerRobot` puts drivers, then skillsets, in native sidecars gated by startup probes, the executors
in the main containers and the plugin folder in an `emptyDir`; the instance status reads the same
in both layouts. The golden files hold one full pod manifest per layout: regenerate them with
`CORAL_UPDATE_GOLDEN=1` after a deliberate change and review the diff.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import yaml
from coral_core import names
from coral_operator.api.instance import CoralInstanceSpec
from coral_operator.api.system import ROBOT_POD_BLOCKS, CoralSystemSpec, StartupSpec
from coral_operator.kube import observing
from coral_operator.planning import instances, naming, pods, policy, startup
from coral_operator.planning.observed import ObservedPod
from coral_operator.status import instance_status
from operator_specs import NOW, instance_view, robot

GOLDEN = Path(__file__).parent / "golden"
EXAMPLE = Path(__file__).parents[3] / "examples" / "lidar-slam" / "mission.yaml"
START = "2026-01-01T11:59:00Z"


def _instance_spec(spec: dict[str, Any]) -> CoralInstanceSpec:
    template = instances.build_template(CoralSystemSpec.model_validate(spec), "tree-cm", "params-cm")
    return CoralInstanceSpec.model_validate(instances.build_instance_spec("sys", robot("r1"), template))


# The examples' bags are a robot folder the missions' administrator opens for their namespace.
SETTINGS = pods.PodSettings(policy=policy.Policy(host_paths=(("ns", "/var/lib/coral/bags"),)))


def _pods(spec: dict[str, Any]) -> list[dict[str, Any]]:
    return pods.build_pods(
        spec=_instance_spec(spec), instance="sys-r1", namespace="ns", instance_uid="u", settings=SETTINGS
    )


def _robot_pod(spec: dict[str, Any]) -> dict[str, Any]:
    (pod,) = _pods({**spec, "layout": "PodPerRobot"})
    return pod


def _volume_kinds(pod: dict[str, Any]) -> set[str]:
    return {key for volume in pod["spec"]["volumes"] for key in volume if key != "name"}


def test_both_layouts_run_the_same_containers(spec_dict: Callable[..., dict[str, Any]]) -> None:
    spec = spec_dict(ros={"network": "Pod"})
    per_component = _pods(spec)
    robot_pod = _robot_pod(spec)
    assert len(per_component) == 3
    containers = {c["name"]: c for m in per_component for c in m["spec"]["containers"]}
    in_robot_pod = {
        c["name"]: c for c in robot_pod["spec"]["initContainers"] + robot_pod["spec"]["containers"]
    }
    assert containers.keys() == in_robot_pod.keys()
    for name, container in containers.items():
        # The same image, command, environment and identity settings; only mounts and probes move.
        for key in ("image", "env", "securityContext", "command", "args"):
            assert in_robot_pod[name].get(key) == container.get(key), (name, key)


def test_drivers_then_skillsets_are_sidecars_in_compose_order(
    spec_dict: Callable[..., dict[str, Any]],
) -> None:
    spec = spec_dict(
        drivers=[{"name": "lidar", "image": "l:1"}, {"name": "imu", "image": "i:1"}],
        skillsets=[{"name": "slam", "image": "s:1"}, {"name": "nav", "image": "n:1"}],
        executors=[{"name": "executor", "image": "e:1"}],
    )
    pod = _robot_pod(spec)
    sidecars = pod["spec"]["initContainers"]
    assert [c["name"] for c in sidecars] == ["lidar", "imu", "slam", "nav"]
    assert all(c["restartPolicy"] == "Always" for c in sidecars)
    assert [c["name"] for c in pod["spec"]["containers"]] == ["executor"]
    assert "restartPolicy" not in pod["spec"]["containers"][0]
    # A finished mission leaves the pod Succeeded, as the executor's own pod does in the other layout.
    assert pod["spec"]["restartPolicy"] == "OnFailure"


def test_a_skillset_is_gated_by_the_same_check_as_its_readiness_gate(
    spec_dict: Callable[..., dict[str, Any]],
) -> None:
    spec = spec_dict(startup={"healthTimeoutSeconds": 60})
    (slam_pod,) = [m for m in _pods(spec) if m["metadata"]["labels"][names.LABEL_COMPONENT] == "slam"]
    readiness = slam_pod["spec"]["containers"][0]["readinessProbe"]
    slam = next(c for c in _robot_pod(spec)["spec"]["initContainers"] if c["name"] == "slam")
    assert slam["startupProbe"]["exec"] == readiness["exec"]
    assert slam["readinessProbe"] == readiness
    # The kubelet restarts a sidecar whose startup probe keeps failing; not before the health timeout.
    assert slam["startupProbe"]["periodSeconds"] * slam["startupProbe"]["failureThreshold"] >= 60
    lidar = next(c for c in _robot_pod(spec)["spec"]["initContainers"] if c["name"] == "lidar")
    assert "startupProbe" not in lidar  # no readiness gate in the other layout either


def test_the_plugin_folder_is_an_empty_dir_and_no_host_path_is_needed(
    spec_dict: Callable[..., dict[str, Any]],
) -> None:
    spec = spec_dict(ros={"network": "Pod"})
    pod = _robot_pod(spec)
    assert "hostPath" not in _volume_kinds(pod)
    assert {"name": "plugins", "emptyDir": {}} in pod["spec"]["volumes"]
    for container in pod["spec"]["initContainers"] + pod["spec"]["containers"]:
        assert {"name": "plugins", "mountPath": "/var/lib/coral/plugins"} in container["volumeMounts"]
    assert not pod["spec"]["hostNetwork"] and not pod["spec"]["hostIPC"]
    assert all("hostPath" in _volume_kinds(m) for m in _pods(spec))


def test_the_host_network_and_host_paths_carry_over_to_the_robot_pod(
    spec_dict: Callable[..., dict[str, Any]],
) -> None:
    spec = spec_dict(
        drivers=[
            {"name": "lidar", "image": "l:1", "devices": [{"hostPath": "/dev/ttyUSB0"}]},
            {"name": "imu", "image": "i:1", "devices": [{"hostPath": "/dev/ttyUSB1"}]},
        ]
    )
    pod = _robot_pod(spec)
    assert pod["spec"]["hostNetwork"] and pod["spec"]["hostIPC"]
    paths = {v["name"]: v["hostPath"]["path"] for v in pod["spec"]["volumes"] if "hostPath" in v}
    assert sorted(paths.values()) == ["/dev/ttyUSB0", "/dev/ttyUSB1"]
    assert len(paths) == 2  # each component's volumes keep their own names in the shared pod
    lidar, imu, _slam = pod["spec"]["initContainers"]
    assert {m["mountPath"] for m in lidar["volumeMounts"]} >= {"/dev/ttyUSB0"}
    assert "/dev/ttyUSB0" not in {m["mountPath"] for m in imu["volumeMounts"]}


def test_only_the_executors_get_the_api_identity(spec_dict: Callable[..., dict[str, Any]]) -> None:
    pod = _robot_pod(spec_dict())
    assert pod["spec"]["automountServiceAccountToken"] is False
    assert pod["spec"]["serviceAccountName"] == naming.executor_account_name("sys")
    for container in pod["spec"]["initContainers"]:
        assert pods.SERVICE_ACCOUNT_DIR not in {m["mountPath"] for m in container["volumeMounts"]}
    (executor,) = pod["spec"]["containers"]
    assert {"name": "executor-token", "mountPath": pods.SERVICE_ACCOUNT_DIR, "readOnly": True} in executor[
        "volumeMounts"
    ]


def test_a_transient_driver_runs_beside_the_executor_and_is_not_restarted(
    spec_dict: Callable[..., dict[str, Any]],
) -> None:
    spec = spec_dict(drivers=[{"name": "bag", "image": "b:1", "transient": True}])
    pod = _robot_pod(spec)
    assert [c["name"] for c in pod["spec"]["initContainers"]] == ["slam"]
    assert [c["name"] for c in pod["spec"]["containers"]] == ["bag", "executor"]


def test_proceed_on_timeout_is_refused_with_one_pod_per_robot(
    spec_dict: Callable[..., dict[str, Any]],
) -> None:
    with pytest.raises(ValueError, match="onTimeout Proceed needs layout PodPerComponent"):
        CoralSystemSpec.model_validate(spec_dict(layout="PodPerRobot", startup={"onTimeout": "Proceed"}))
    assert "PodPerComponent" in ROBOT_POD_BLOCKS


def test_the_layout_is_part_of_the_revision_but_the_default_keeps_old_revisions(
    spec_dict: Callable[..., dict[str, Any]],
) -> None:
    default = instances.build_template(CoralSystemSpec.model_validate(spec_dict()), "t", "p")
    explicit = instances.build_template(
        CoralSystemSpec.model_validate(spec_dict(layout="PodPerComponent")), "t", "p"
    )
    robot_pod = instances.build_template(
        CoralSystemSpec.model_validate(spec_dict(layout="PodPerRobot")), "t", "p"
    )
    assert "layout" not in default
    assert instances.revision_of(default) == instances.revision_of(explicit)
    assert instances.revision_of(robot_pod) != instances.revision_of(default)


# --- planning the robot pod -------------------------------------------------------------------


def _container_status(name: str, *, ready: bool, started: bool = True, **extra: Any) -> dict[str, Any]:
    state = {"running": {"startedAt": START}} if started else {"waiting": {"reason": "PodInitializing"}}
    return {"name": name, "ready": ready, "restartCount": 0, "state": state, **extra}


def _robot_pod_body(
    manifest: dict[str, Any], ready: set[str], started: set[str] | None = None, phase: str = "Running"
) -> dict[str, Any]:
    started = set(ready) if started is None else started
    spec = manifest["spec"]
    return {
        "metadata": {**manifest["metadata"], "creationTimestamp": START},
        "spec": spec,
        "status": {
            "phase": phase,
            "initContainerStatuses": [
                _container_status(c["name"], ready=c["name"] in ready, started=c["name"] in started)
                for c in spec["initContainers"]
            ],
            "containerStatuses": [
                _container_status(c["name"], ready=c["name"] in ready, started=c["name"] in started)
                for c in spec["containers"]
            ],
        },
    }


def _plan(desired: list[dict[str, Any]], observed: list[ObservedPod]) -> startup.StartupPlan:
    return startup.plan_startup(
        desired=desired, observed=observed, transient=set(), startup=StartupSpec(), now=NOW
    )


def test_a_new_robot_gets_its_whole_pod_at_once(spec_dict: Callable[..., dict[str, Any]]) -> None:
    desired = _pods(spec_dict(layout="PodPerRobot"))
    plan = _plan(desired, [])
    assert plan.create == desired and not plan.delete


def test_the_status_waits_for_the_stage_the_kubelet_waits_for(
    spec_dict: Callable[..., dict[str, Any]],
) -> None:
    desired = _pods(spec_dict(layout="PodPerRobot"))
    observed = list(observing.observed_pods(_robot_pod_body(desired[0], ready=set(), started={"lidar"})))
    plan = _plan(desired, observed)
    assert (plan.waiting_for, plan.create, plan.delete) == ("driver", [], [])
    observed = list(
        observing.observed_pods(_robot_pod_body(desired[0], ready={"lidar"}, started={"lidar", "slam"}))
    )
    assert _plan(desired, observed).waiting_for == "skillset"
    observed = list(observing.observed_pods(_robot_pod_body(desired[0], ready={"lidar", "slam", "executor"})))
    assert _plan(desired, observed).waiting_for is None


def test_a_changed_component_replaces_the_pod_once_the_old_one_is_gone(
    spec_dict: Callable[..., dict[str, Any]],
) -> None:
    old = _pods(spec_dict(layout="PodPerRobot"))
    new = _pods(
        spec_dict(
            layout="PodPerRobot",
            skillsets=[{"name": "slam", "image": "example/slam:1", "env": [{"name": "A", "value": "1"}]}],
        )
    )
    running = list(observing.observed_pods(_robot_pod_body(old[0], ready={"lidar", "slam", "executor"})))
    plan = _plan(new, running)
    assert plan.delete == [old[0]["metadata"]["name"]] and not plan.create and not plan.set_images
    stopping = [ObservedPod(**{**r.__dict__, "deleting": True}) for r in running]
    assert _plan(new, stopping).create == []
    assert _plan(new, []).create == new


def test_an_image_only_change_is_patched_into_the_running_pod(
    spec_dict: Callable[..., dict[str, Any]],
) -> None:
    old = _pods(spec_dict(layout="PodPerRobot"))
    new = _pods(spec_dict(layout="PodPerRobot", skillsets=[{"name": "slam", "image": "example/slam:2"}]))
    running = list(observing.observed_pods(_robot_pod_body(old[0], ready={"lidar", "slam", "executor"})))
    plan = _plan(new, running)
    assert not plan.delete and not plan.create
    ((name, patch),) = plan.set_images
    assert name == old[0]["metadata"]["name"]
    assert patch["spec"] == {"initContainers": [{"name": "slam", "image": "example/slam:2"}]}
    assert (
        patch["metadata"]["annotations"][names.ANNOTATION_POD_HASH]
        == new[0]["metadata"]["annotations"][names.ANNOTATION_POD_HASH]
    )


def test_changing_the_layout_stops_the_old_pods_before_starting_the_new(
    spec_dict: Callable[..., dict[str, Any]],
) -> None:
    per_component = _pods(spec_dict())
    running = [observing.observed_pod({**m, "status": {"phase": "Running"}}) for m in per_component]
    robot_pod = _pods(spec_dict(layout="PodPerRobot"))
    plan = _plan(robot_pod, running)
    assert sorted(plan.delete) == sorted(m["metadata"]["name"] for m in per_component)
    assert plan.create == []
    back = _plan(per_component, list(observing.observed_pods(_robot_pod_body(robot_pod[0], ready={"lidar"}))))
    assert back.delete == [robot_pod[0]["metadata"]["name"]] and back.create == []


def test_a_retiring_robot_deletes_its_one_pod(spec_dict: Callable[..., dict[str, Any]]) -> None:
    desired = _pods(spec_dict(layout="PodPerRobot"))
    observed = list(observing.observed_pods(_robot_pod_body(desired[0], ready={"lidar", "slam", "executor"})))
    assert startup.plan_shutdown(observed) == [desired[0]["metadata"]["name"]]


# --- the same status in both layouts ---------------------------------------------------------


def _status(
    spec: dict[str, Any], bodies: list[dict[str, Any]], plugins: dict | None = None
) -> dict[str, Any]:
    parsed = _instance_spec(spec)
    desired = pods.build_pods(spec=parsed, instance="sys-r1", namespace="ns", instance_uid="u")
    observed = [record for body in bodies for record in observing.observed_pods(body)]
    view = instance_view(
        parsed, desired, observed, startup=parsed.startup, tree={"rootStatus": "RUNNING"}, plugins=plugins
    )
    status = instance_status.build_instance_status(view, old_conditions=[], generation=1, now=NOW)
    for entry in status["components"]:
        entry.pop("pod", None)
        entry.pop("revision", None)
    status.pop("revision")  # each layout has its own revision
    for condition in status["conditions"]:
        condition["message"] = condition["message"].replace(parsed.revision, "<revision>")
    return status


def _component_body(manifest: dict[str, Any], ready: bool, **status: Any) -> dict[str, Any]:
    conditions = [{"type": "Ready", "status": "True" if ready else "False"}]
    container = {
        "name": manifest["spec"]["containers"][0]["name"],
        "ready": ready,
        "restartCount": 0,
        **status,
    }
    return {
        "metadata": {**manifest["metadata"], "creationTimestamp": START},
        "status": {"phase": "Running", "conditions": conditions, "containerStatuses": [container]},
    }


@pytest.mark.parametrize("ready", [{"lidar", "slam", "executor"}, {"lidar"}, {"lidar", "slam"}])
def test_the_instance_status_reads_the_same_in_both_layouts(
    spec_dict: Callable[..., dict[str, Any]], ready: set[str]
) -> None:
    spec = spec_dict()
    per_component = _pods(spec)
    started = (
        {"lidar"} | ({"slam"} if "lidar" in ready else set()) | ({"executor"} if "slam" in ready else set())
    )
    bodies = [
        _component_body(m, m["metadata"]["labels"][names.LABEL_COMPONENT] in ready)
        for m in per_component
        if m["metadata"]["labels"][names.LABEL_COMPONENT] in started
    ]
    robot_spec = {**spec, "layout": "PodPerRobot"}
    robot_body = _robot_pod_body(_pods(robot_spec)[0], ready=ready, started=started)
    degraded = {"degraded": ["slam"], "loaded": ["slam"], "missing": []}
    assert _status(spec, bodies, degraded) == _status(robot_spec, [robot_body], degraded)


def test_a_crashing_skillset_container_is_named_like_a_crashing_skillset_pod(
    spec_dict: Callable[..., dict[str, Any]],
) -> None:
    robot_spec = spec_dict(layout="PodPerRobot")
    body = _robot_pod_body(_pods(robot_spec)[0], ready={"lidar", "executor"})
    slam = body["status"]["initContainerStatuses"][1]
    slam["state"] = {"waiting": {"reason": "CrashLoopBackOff", "message": "back-off"}}
    slam["restartCount"] = 4
    status = _status(robot_spec, [body])
    ready = next(c for c in status["conditions"] if c["type"] == "Ready")
    assert (ready["reason"], ready["message"]) == ("ComponentFailed", "Components failing: slam.")
    assert next(c for c in status["components"] if c["name"] == "slam")["restarts"] == 4


# --- golden manifests -------------------------------------------------------------------------


def _example_spec() -> dict[str, Any]:
    return yaml.safe_load(EXAMPLE.read_text())["spec"]


def _golden(name: str, manifest: dict[str, Any]) -> None:
    path = GOLDEN / name
    text = json.dumps(manifest, indent=2, sort_keys=True) + "\n"
    if os.environ.get("CORAL_UPDATE_GOLDEN"):
        path.write_text(text)
    assert text == path.read_text(), f"{path} differs; regenerate with CORAL_UPDATE_GOLDEN=1 if deliberate"


def test_golden_pod_per_component_skillset_pod() -> None:
    (slam,) = [m for m in _pods(_example_spec()) if m["metadata"]["labels"][names.LABEL_COMPONENT] == "slam"]
    _golden("lidar-slam-pod-per-component-slam.json", slam)


def test_golden_pod_per_robot_pod() -> None:
    _golden("lidar-slam-pod-per-robot.json", _robot_pod(_example_spec()))


def test_a_finished_mission_reads_the_same_in_both_layouts(spec_dict: Callable[..., dict[str, Any]]) -> None:
    spec = spec_dict()
    finished = {"state": {"terminated": {"exitCode": 0, "startedAt": START, "finishedAt": START}}}
    bodies = []
    for manifest in _pods(spec):
        executor = manifest["metadata"]["labels"][names.LABEL_ROLE] == "executor"
        body = _component_body(manifest, not executor, **(finished if executor else {}))
        if executor:
            body["status"]["phase"] = "Succeeded"
        bodies.append(body)
    robot_spec = {**spec, "layout": "PodPerRobot"}
    robot_body = _robot_pod_body(_pods(robot_spec)[0], ready=set(), phase="Succeeded")
    stopped = {"state": {"terminated": {"exitCode": 143, "startedAt": START, "finishedAt": START}}}
    for status in robot_body["status"]["initContainerStatuses"]:
        status.update(stopped)  # the kubelet stops the sidecars once the executor ended
    robot_body["status"]["containerStatuses"][0].update(finished)
    per_component, per_robot = _status(spec, bodies), _status(robot_spec, [robot_body])
    conditions = {c["type"]: (c["status"], c["reason"]) for c in per_robot["conditions"]}
    assert conditions["Ready"] == ("True", "Ready")
    assert conditions == {c["type"]: (c["status"], c["reason"]) for c in per_component["conditions"]}
    assert [(c["name"], c["ready"]) for c in per_robot["components"]] == [
        (c["name"], c["ready"]) for c in per_component["components"]
    ]


def test_a_sidecar_restarted_by_its_startup_probe_still_times_out(
    spec_dict: Callable[..., dict[str, Any]],
) -> None:
    desired = _pods(spec_dict(layout="PodPerRobot", startup={"healthTimeoutSeconds": 30}))
    body = _robot_pod_body(desired[0], ready={"lidar"}, started={"lidar", "slam"})
    slam = body["status"]["initContainerStatuses"][1]
    # Restarted a moment ago, in a pod made a minute ago: the wait counts from the pod.
    slam["state"] = {"running": {"startedAt": "2026-01-01T11:59:58Z"}}
    slam["restartCount"] = 2
    observed = list(observing.observed_pods(body))
    plan = startup.plan_startup(
        desired=desired,
        observed=observed,
        transient=set(),
        startup=StartupSpec(health_timeout_seconds=30),
        now=NOW,
    )
    assert (plan.waiting_for, plan.timed_out) == ("skillset", True)
    assert "Skillsets not ready after 30 s (slam)" in plan.message
