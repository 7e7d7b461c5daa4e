"""The operator's pods of a system that may run offline wait for the robot's offline copy to stop."""

from __future__ import annotations

from coral_core import names, offline
from offline_pods import robot_pods, system


def _by_part(pods: list[dict]) -> dict[str, dict]:
    return {p["metadata"]["labels"].get(names.LABEL_COMPONENT, "robot"): p for p in pods}


def test_off_by_default_and_the_pods_are_unchanged() -> None:
    default = robot_pods(system())
    explicit = robot_pods(system(offline={"mode": "Off"}))
    assert [p["metadata"]["name"] for p in default] == [p["metadata"]["name"] for p in explicit]
    for pod in default:
        assert offline.LABEL_OFFLINE not in pod["metadata"]["labels"]
        inits = pod["spec"].get("initContainers", [])
        assert offline.GATE_CONTAINER not in [c["name"] for c in inits]


def test_every_pod_first_waits_for_its_own_components_lock() -> None:
    pods = _by_part(robot_pods(system(offline={"mode": "LastRevision"})))
    locks = set()
    for part, pod in pods.items():
        gate = pod["spec"]["initContainers"][0]
        assert gate["name"] == offline.GATE_CONTAINER
        assert gate["command"][0] == "flock"
        assert gate["command"][1].endswith(offline.lock_name("ns", "sys", part))
        locks.add(gate["command"][1])
        assert pod["metadata"]["labels"][offline.LABEL_OFFLINE] == "LastRevision"
        assert pod["metadata"]["annotations"][offline.ANNOTATION_INTERRUPT] == "false"
        paths = [v["hostPath"]["path"] for v in pod["spec"]["volumes"] if "hostPath" in v]
        assert offline.LOCKS_DIR in paths
    assert len(locks) == 3


def test_turning_offline_on_is_a_new_revision_and_follows_the_update_lock() -> None:
    off = robot_pods(system())
    on = robot_pods(system(offline={"mode": "LastRevision"}, rollout={"interruptRunningTrees": True}))
    revision = names.LABEL_REVISION
    assert off[0]["metadata"]["labels"][revision] != on[0]["metadata"]["labels"][revision]
    assert all(p["metadata"]["annotations"][offline.ANNOTATION_INTERRUPT] == "true" for p in on)


def test_a_robot_pod_has_one_gate() -> None:
    (pod,) = robot_pods(system(offline={"mode": "LastRevision"}, layout="PodPerRobot"))
    gates = [c for c in pod["spec"]["initContainers"] if c["name"] == offline.GATE_CONTAINER]
    assert len(gates) == 1
    assert gates[0]["command"][1].endswith(offline.lock_name("ns", "sys", "robot"))
