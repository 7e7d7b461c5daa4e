"""A component's pod runs on its robot, survives the robot dropping off, and gets Coral's environment."""

from __future__ import annotations

import re
from collections.abc import Callable
from typing import Any

import pytest
from coral_core import names
from coral_operator.api.instance import CoralInstanceSpec
from coral_operator.api.system import CoralSystemSpec
from coral_operator.planning import instances, naming, pods
from operator_specs import robot

DNS_SUBDOMAIN = re.compile(r"[a-z0-9]([-a-z0-9]*[a-z0-9])?(\.[a-z0-9]([-a-z0-9]*[a-z0-9])?)*")


def _instance_spec(spec: dict[str, Any]) -> CoralInstanceSpec:
    template = instances.build_template(CoralSystemSpec.model_validate(spec), "sys-tree-1", "sys-params-1")
    return CoralInstanceSpec.model_validate(instances.build_instance_spec("sys", robot("r1"), template))


def _pods(spec: dict[str, Any]) -> dict[str, dict[str, Any]]:
    built = pods.build_pods(
        spec=_instance_spec(spec), instance="sys-r1", namespace="ns", instance_uid="uid-1"
    )
    return {p["metadata"]["labels"][names.LABEL_COMPONENT]: p for p in built}


def _env(pod: dict[str, Any]) -> dict[str, Any]:
    return {e["name"]: e.get("value", e.get("valueFrom")) for e in pod["spec"]["containers"][0]["env"]}


def test_one_pod_per_component_in_startup_order(spec_dict: Callable[..., dict[str, Any]]) -> None:
    built = pods.build_pods(
        spec=_instance_spec(spec_dict()), instance="sys-r1", namespace="ns", instance_uid="u"
    )
    assert [p["metadata"]["labels"][names.LABEL_COMPONENT] for p in built] == ["lidar", "slam", "executor"]
    for pod in built:
        component = pod["metadata"]["labels"][names.LABEL_COMPONENT]
        assert re.fullmatch(rf"sys-r1-{component}-[a-z0-9]{{5}}", pod["metadata"]["name"])


def test_pod_names_follow_the_content(spec_dict: Callable[..., dict[str, Any]]) -> None:
    before = _pods(spec_dict())
    assert {k: v["metadata"]["name"] for k, v in _pods(spec_dict()).items()} == {
        k: v["metadata"]["name"] for k, v in before.items()
    }
    after = _pods(spec_dict(executors=[{"name": "executor", "image": "example/executor:2"}]))
    # A new revision alone renames nothing: the unchanged pods are relabelled, not replaced.
    assert after["lidar"]["metadata"]["name"] == before["lidar"]["metadata"]["name"]
    assert after["slam"]["metadata"]["name"] == before["slam"]["metadata"]["name"]
    assert after["executor"]["metadata"]["name"] != before["executor"]["metadata"]["name"]
    assert after["executor"]["metadata"]["name"].startswith("sys-r1-executor-")


def test_the_pod_hash_does_not_cover_the_name(spec_dict: Callable[..., dict[str, Any]]) -> None:
    pod = _pods(spec_dict())["slam"]
    assert pod["metadata"]["name"] == naming.pod_name(
        "sys-r1", "slam", pod["metadata"]["annotations"][names.ANNOTATION_POD_HASH]
    )


@pytest.mark.parametrize("instance", ["a" * 63, "b" * 250, "Fleet.Robot_7" * 30])
def test_pod_names_stay_valid_for_long_instance_names(instance: str) -> None:
    names = {
        naming.pod_name(instance, c, h) for c in ("lidar", "l" * 40) for h in ("0123456789", "abcdef0123")
    }
    assert len(names) == 4
    for name in names:
        assert len(name) <= 253
        assert DNS_SUBDOMAIN.fullmatch(name), name
        assert re.fullmatch(r".*-[a-z0-9]{5}", name)


def test_pods_are_pinned_to_the_robot_and_never_evicted(spec_dict: Callable[..., dict[str, Any]]) -> None:
    for pod in _pods(spec_dict()).values():
        assert pod["spec"]["nodeName"] == "r1"
        no_execute = {t["key"] for t in pod["spec"]["tolerations"] if t["effect"] == "NoExecute"}
        assert no_execute == {"node.kubernetes.io/unreachable", "node.kubernetes.io/not-ready"}
        assert all("tolerationSeconds" not in t for t in pod["spec"]["tolerations"])
        assert pod["metadata"]["ownerReferences"][0]["kind"] == "CoralInstance"


def test_host_network_and_ipc_by_default_and_pod_network_on_request(
    spec_dict: Callable[..., dict[str, Any]],
) -> None:
    pod = _pods(spec_dict())["slam"]
    assert pod["spec"]["hostNetwork"] and pod["spec"]["hostIPC"]
    pod = _pods(spec_dict(ros={"network": "Pod"}))["slam"]
    assert not pod["spec"]["hostNetwork"] and not pod["spec"]["hostIPC"]


def test_every_pod_gets_the_ros_environment_and_the_plugin_volume(
    spec_dict: Callable[..., dict[str, Any]],
) -> None:
    for pod in _pods(spec_dict(ros={"domainId": 42, "localhostOnly": True})).values():
        env = _env(pod)
        assert env["ROS_DOMAIN_ID"] == "42"
        assert env["RMW_IMPLEMENTATION"] == "rmw_fastrtps_cpp"
        assert env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"
        assert env["CORAL_PLUGIN_DIR"] == "/var/lib/coral/plugins"
        volumes = {v["name"]: v for v in pod["spec"]["volumes"]}
        assert volumes["plugins"]["hostPath"]["path"] == "/var/lib/coral/plugins/ns/sys"


def test_only_executors_get_the_tree_and_a_service_account(spec_dict: Callable[..., dict[str, Any]]) -> None:
    built = _pods(spec_dict())
    executor, driver = built["executor"], built["lidar"]
    sources = [s["configMap"]["name"] for s in executor["spec"]["volumes"][1]["projected"]["sources"]]
    assert sources == ["sys-params-1", "sys-tree-1"]
    assert executor["spec"]["serviceAccountName"] == "coral-executor-sys"
    assert executor["spec"]["automountServiceAccountToken"] is True
    assert _env(executor)["CORAL_INSTANCE"] == "sys-r1"
    assert "--sink" in executor["spec"]["containers"][0]["command"]
    assert "serviceAccountName" not in driver["spec"]
    assert driver["spec"]["automountServiceAccountToken"] is False
    assert [s["configMap"]["name"] for s in driver["spec"]["volumes"][1]["projected"]["sources"]] == [
        "sys-params-1"
    ]


def test_skillsets_are_ready_when_their_plugin_marker_exists(
    spec_dict: Callable[..., dict[str, Any]],
) -> None:
    probe = _pods(spec_dict())["slam"]["spec"]["containers"][0]["readinessProbe"]
    assert probe["exec"]["command"] == ["test", "-f", "/var/lib/coral/plugins/slam/ready"]
    assert "readinessProbe" not in _pods(spec_dict())["lidar"]["spec"]["containers"][0]


def test_components_run_as_non_root_unless_privileged(spec_dict: Callable[..., dict[str, Any]]) -> None:
    built = _pods(
        spec_dict(
            drivers=[
                {"name": "lidar", "image": "l", "privileged": True, "devices": [{"hostPath": "/dev/ttyUSB0"}]}
            ]
        )
    )
    assert built["lidar"]["spec"]["containers"][0]["securityContext"] == {"privileged": True}
    assert built["slam"]["spec"]["containers"][0]["securityContext"]["runAsNonRoot"] is True
    mounts = {m["mountPath"] for m in built["lidar"]["spec"]["containers"][0]["volumeMounts"]}
    assert "/dev/ttyUSB0" in mounts


def test_non_root_components_get_the_plugin_folder_through_a_chown_only_init_step(
    spec_dict: Callable[..., dict[str, Any]],
) -> None:
    built = _pods(
        spec_dict(
            drivers=[
                {"name": "lidar", "image": "l", "privileged": True, "devices": [{"hostPath": "/dev/ttyUSB0"}]}
            ]
        )
    )
    slam = built["slam"]["spec"]
    (owner,) = slam["initContainers"]
    # The kubelet creates the host path root-owned 0755: the step gives it to the components' user
    # with CAP_CHOWN alone, and the skillset itself stays non-root. The step runs the operator's
    # helper image, never the component's (issue 47: its own `chown` ran as root on the robot).
    assert owner["command"] == ["chown", "--no-dereference", "10001:10001", "/coral-owned/plugins"]
    assert owner["image"] == pods.DEFAULT_HELPER_IMAGE != slam["containers"][0]["image"]
    assert owner["securityContext"]["capabilities"] == {"drop": ["ALL"], "add": ["CHOWN"]}
    assert owner["securityContext"]["allowPrivilegeEscalation"] is False
    assert [m["name"] for m in owner["volumeMounts"]] == ["plugins"]
    assert slam["containers"][0]["securityContext"]["runAsNonRoot"] is True
    # A privileged (root) driver writes the folder as it is.
    assert "initContainers" not in built["lidar"]["spec"]


def test_a_new_revision_changes_only_the_pods_whose_component_changed(
    spec_dict: Callable[..., dict[str, Any]],
) -> None:
    before = _pods(spec_dict())
    after = _pods(spec_dict(executors=[{"name": "executor", "image": "example/executor:2"}]))
    hash_of = {k: v["metadata"]["annotations"][names.ANNOTATION_POD_HASH] for k, v in before.items()}
    assert after["lidar"]["metadata"]["annotations"][names.ANNOTATION_POD_HASH] == hash_of["lidar"]
    assert after["slam"]["metadata"]["annotations"][names.ANNOTATION_POD_HASH] == hash_of["slam"]
    assert after["executor"]["metadata"]["annotations"][names.ANNOTATION_POD_HASH] != hash_of["executor"]
    assert (
        after["lidar"]["metadata"]["labels"][names.LABEL_REVISION]
        != before["lidar"]["metadata"]["labels"][names.LABEL_REVISION]
    )


def test_pod_labels_are_curated(spec_dict: Callable[..., dict[str, Any]]) -> None:
    labels = _pods(spec_dict())["slam"]["metadata"]["labels"]
    assert labels[names.LABEL_SYSTEM] == "sys"
    assert labels[names.LABEL_ROBOT] == "r1"
    assert labels[names.LABEL_ROLE] == "skillset"
    assert "fleet" not in labels
