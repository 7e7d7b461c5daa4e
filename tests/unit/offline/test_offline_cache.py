"""What a robot keeps of its last revision, and the check that refuses an altered copy."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from coral.offline import store
from coral.offline.staticpods import static_copy
from coral_core import names, offline
from offline_pods import CONFIG_MAPS, PARAMS, TREE, robot_pods, system


def _copies() -> dict[str, offline.CacheManifest]:
    pods = robot_pods(system(offline={"mode": "LastRevision"}))
    return {
        p["metadata"]["labels"][names.LABEL_COMPONENT]: static_copy(
            p, config_maps=CONFIG_MAPS, files_dir="/cache/files", run_dir="/runs/ns_sys"
        )
        for p in pods
    }


def test_the_static_copy_refers_to_nothing_the_robot_cannot_read_offline() -> None:
    copies = _copies()
    executor = copies["executor"].pod
    volumes = {v["name"]: v for v in executor["spec"]["volumes"]}
    assert all("configMap" not in v and "projected" not in v for v in volumes.values())
    assert volumes["config"]["hostPath"]["path"] == "/cache/files/config"
    assert copies["executor"].files == {
        "config/tree.xml": TREE.encode(),
        "config/params.yaml": PARAMS.encode(),
    }
    assert copies["slam"].files == {"config/params.yaml": PARAMS.encode()}
    spec = executor["spec"]
    assert "serviceAccountName" not in spec and "nodeName" not in spec
    assert spec["automountServiceAccountToken"] is False
    (container,) = spec["containers"]
    assert container["imagePullPolicy"] == "Never"
    assert "--sink" not in container["command"]
    assert container["command"][-2:] == ["--status-jsonl", f"{offline.RUN_MOUNT}/{offline.STATUS_FILE}"]
    mounted = {m["name"] for m in container["volumeMounts"]}
    assert mounted <= set(volumes)


def test_the_static_copy_holds_its_lock_and_is_not_one_of_the_operators_pods() -> None:
    for part, copy in _copies().items():
        labels = copy.pod["metadata"]["labels"]
        assert names.LABEL_INSTANCE not in labels and names.LABEL_MANAGED_BY not in labels
        assert labels[offline.LABEL_OFFLINE_COPY] == part
        holder = copy.pod["spec"]["initContainers"][0]
        assert holder["name"] == offline.HOLDER_CONTAINER
        assert holder["restartPolicy"] == "Always"
        assert holder["command"][-1] == f"{offline.LOCK_MOUNT}/{offline.lock_name('ns', 'sys', part)}"
        names_ = [c["name"] for c in copy.pod["spec"]["initContainers"]]
        assert offline.GATE_CONTAINER not in names_


def test_a_pod_of_a_system_that_does_not_run_offline_is_never_copied() -> None:
    (pod, *_) = robot_pods(system())
    with pytest.raises(ValueError, match="offline-gate"):
        static_copy(pod, config_maps=CONFIG_MAPS, files_dir="/f", run_dir="/r")


def _manifest(robot: str = "r1") -> offline.CacheManifest:
    return offline.CacheManifest(
        namespace="ns",
        system="sys",
        instance="sys-r1",
        instance_uid="uid-1",
        robot=robot,
        revision="abc",
        recorded_at="2026-01-01T00:00:00Z",
        interrupt_running_trees=False,
        pods=[{"kind": "Pod"}],
        files={"executor/config/tree.xml": offline.file_digest(TREE.encode())},
        images={"executor/executor": "sha256:1"},
    )


@pytest.fixture
def stored(tmp_path: Path) -> Path:
    folder = tmp_path / "systems" / "ns_sys"
    store.write_cache(
        folder, _manifest(), {"executor/config/tree.xml": TREE.encode()}, store.robot_key(tmp_path), "src"
    )
    return folder


def _verify(root: Path, robot: str = "r1") -> offline.Verdict:
    return store.verify(root, "ns_sys", store.robot_key(root), robot)


def test_an_untouched_cache_passes_and_the_key_is_the_robots_alone(tmp_path: Path, stored: Path) -> None:
    verdict = _verify(tmp_path)
    assert verdict.manifest == _manifest()
    assert (tmp_path / "key").stat().st_mode & 0o777 == 0o600


@pytest.mark.parametrize(
    ("alter", "reason"),
    [
        (lambda f: (f / "files/executor/config/tree.xml").write_text("<root/>"), "was altered"),
        (lambda f: (f / "files/executor/config/extra.py").write_text("x"), "not in the manifest"),
        (lambda f: (f / "files/executor/config/tree.xml").unlink(), "is missing"),
        (
            lambda f: (f / "manifest.json").write_text(
                (f / "manifest.json").read_text().replace('"revision":"abc"', '"revision":"evil"')
            ),
            "does not match its seal",
        ),
        (lambda f: (f / "seal").unlink(), "incomplete"),
    ],
)
def test_an_altered_cache_is_refused_with_the_reason(
    tmp_path: Path, stored: Path, alter, reason: str
) -> None:
    alter(stored)
    verdict = _verify(tmp_path)
    assert verdict.manifest is None
    assert reason in verdict.reason


def test_a_cache_resealed_with_another_key_is_refused(tmp_path: Path, stored: Path) -> None:
    manifest_bytes = (stored / "manifest.json").read_bytes()
    (stored / "seal").write_text(offline.seal(manifest_bytes, b"not the robot's key"))
    assert "does not match its seal" in _verify(tmp_path).reason


def test_another_robots_cache_is_refused(tmp_path: Path, stored: Path) -> None:
    assert "recorded for robot 'r1'" in _verify(tmp_path, robot="r2").reason


def test_recording_again_replaces_the_cache_whole(tmp_path: Path, stored: Path) -> None:
    newer = _manifest()
    store.write_cache(
        stored, newer, {"executor/config/tree.xml": TREE.encode()}, store.robot_key(tmp_path), "s2"
    )
    assert _verify(tmp_path).manifest == newer
    assert sorted(p.name for p in stored.parent.iterdir()) == ["ns_sys"]
    assert json.loads((stored / "manifest.json").read_text())["revision"] == "abc"


def test_a_system_is_recorded_only_once_all_its_pods_run_at_one_revision() -> None:
    pods = robot_pods(system(offline={"mode": "LastRevision"}))
    assert store.all_running(pods)
    assert store.config_map_names(pods) == sorted(CONFIG_MAPS), "the token volume's ConfigMap is not recorded"
    waiting = [dict(p) for p in pods]
    waiting[0] = {**waiting[0], "status": {"phase": "Pending"}}
    assert not store.all_running(waiting)
    moved = [dict(p) for p in pods]
    moved[0] = {**moved[0], "metadata": {**moved[0]["metadata"], "labels": {names.LABEL_REVISION: "other"}}}
    assert not store.all_running(moved)
    relabelled = [{**p, "metadata": {**p["metadata"], "annotations": {}}} for p in pods]
    assert store.fingerprint(relabelled) != store.fingerprint(pods)


def test_a_system_made_again_under_its_name_is_recorded_anew() -> None:
    pods = robot_pods(system(offline={"mode": "LastRevision"}))
    assert all(p["metadata"].get("ownerReferences") for p in pods), "the pods name their instance"
    again = [
        {
            **p,
            "metadata": {
                **p["metadata"],
                "ownerReferences": [{**o, "uid": "uid-2"} for o in p["metadata"]["ownerReferences"]],
            },
        }
        for p in pods
    ]
    assert store.fingerprint(again) != store.fingerprint(pods)
    assert store.fingerprint([dict(p) for p in pods]) == store.fingerprint(pods)
