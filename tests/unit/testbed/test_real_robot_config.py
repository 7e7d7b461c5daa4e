"""A real robot's files and addresses, built without starting anything (no cluster, no root)."""

from __future__ import annotations

import gzip
import hashlib
import io
import json
import tarfile
import tomllib
from pathlib import Path

import pytest
from coral_testbed.cluster import mountview, nodeconfig, nodeimages, robotnet
from coral_testbed.cluster.client import parse_table


def _layout(tmp_path: Path, name: str = "r1", index: int = 0, slot: int = 3) -> nodeconfig.RobotLayout:
    return nodeconfig.RobotLayout(
        name=name,
        slot=slot,
        index=index,
        dir=tmp_path / "robots" / name,
        bin_dir=tmp_path / "bin",
        api_port=6443,
        registry="127.0.0.1:5000",
        ca_cert=tmp_path / "pki" / "ca.crt",
    )


def test_containerd_config_carries_the_traps_and_the_robots_own_paths(tmp_path: Path) -> None:
    layout = _layout(tmp_path)
    config = tomllib.loads(nodeconfig.build_containerd_config(layout))
    cri = config["plugins"]["io.containerd.grpc.v1.cri"]
    assert cri["restrict_oom_score_adj"] is True
    assert cri["sandbox_image"] == nodeimages.SANDBOX_IMAGE
    assert cri["containerd"]["runtimes"]["runc"]["options"]["SystemdCgroup"] is False
    assert cri["cni"]["conf_dir"] == str(layout.cni_conf_dir)
    assert cri["registry"]["config_path"] == str(layout.registry_hosts_dir)
    assert config["grpc"]["address"] == nodeconfig.CONTAINERD_SOCKET
    # containerd's state is a private path of the robot, so two robots never share a socket.
    assert nodeconfig.CONTAINERD_SOCKET.startswith(tuple(mountview.PRIVATE))


def test_registry_hosts_send_coral_local_to_the_registry_over_plain_http() -> None:
    hosts = nodeconfig.build_registry_hosts("127.0.0.1:5123")
    assert set(hosts) == {"coral.local", "127.0.0.1:5123", "docker.io"}
    for name, body in hosts.items():
        parsed = tomllib.loads(body)
        if name != "docker.io":
            assert parsed["server"] == "http://127.0.0.1:5123"
        assert parsed["host"]["http://127.0.0.1:5123"]["capabilities"] == ["pull", "resolve"]


def test_docker_hub_names_are_mirrored_by_the_registry() -> None:
    hub = tomllib.loads(nodeconfig.build_registry_hosts("127.0.0.1:5123")["docker.io"])
    # The registry is tried first; Docker Hub stays the upstream where it is reachable.
    assert hub["server"] == "https://registry-1.docker.io"
    assert list(hub["host"]) == ["http://127.0.0.1:5123"]


@pytest.mark.parametrize(
    "value", ["10.0.0.1:5000", "127.0.0.1", "127.0.0.1:port", "127.0.0.1:70000", "localhost:5000"]
)
def test_registry_address_must_be_loopback_with_a_port(monkeypatch: pytest.MonkeyPatch, value: str) -> None:
    monkeypatch.setenv(nodeconfig.REGISTRY_ENV, value)
    with pytest.raises(ValueError, match=r"CORAL_REGISTRY"):
        nodeconfig.registry_address()


def test_kubelet_config_has_the_cgroup_v1_settings_and_the_robots_address(tmp_path: Path) -> None:
    layout = _layout(tmp_path, index=4)
    config = nodeconfig.build_kubelet_config(layout)
    assert config["failCgroupV1"] is False and config["cgroupDriver"] == "cgroupfs"
    assert config["cgroupRoot"] == layout.cgroup_root == "/coral-3-r1"
    assert config["address"] == layout.link.address == "10.163.0.6"
    assert config["authentication"]["anonymous"]["enabled"] is False
    argv = nodeconfig.build_kubelet(layout, {"coral.dev/robot": "r1", "coral.dev/model": "tb4"})
    assert "--node-labels=coral.dev/model=tb4,coral.dev/robot=r1" in argv
    assert f"--node-ip={layout.link.address}" in argv
    assert argv[: len(nodeconfig.enter_robot(layout))] == nodeconfig.enter_robot(layout)


def test_robots_get_distinct_addresses_pod_subnets_and_names(tmp_path: Path) -> None:
    layouts = [_layout(tmp_path, f"r{i}", i) for i in range(3)]
    assert len({layout.link.address for layout in layouts}) == 3
    subnets = {
        json.dumps(nodeconfig.build_cni_config(layout)["plugins"][0]["ipam"]["ranges"]) for layout in layouts
    }
    assert len(subnets) == 3
    assert len({layout.link.host_veth for layout in layouts}) == 3
    assert all(len(layout.link.host_veth) <= 15 for layout in layouts)
    with pytest.raises(ValueError, match="at most 253"):
        robotnet.robot_address(0, 253)


def test_layout_survives_its_json_round_trip(tmp_path: Path) -> None:
    layout = _layout(tmp_path)
    assert nodeconfig.RobotLayout.from_json(json.loads(json.dumps(layout.to_json()))) == layout


@pytest.mark.parametrize(
    ("path", "private"),
    [
        ("/var/lib/coral/plugins/x", True),
        ("/var/lib/coral", True),
        ("/var/log/pods/ns_pod/c/0.log", True),
        ("/var/lib/coral/../../etc/passwd", False),
        ("/var/lib/coralx", False),
        ("/srv/maps", True),
        ("/srvx/data", False),
        ("/srv/../etc", False),
        ("/etc/coral", False),
    ],
)
def test_host_path_maps_only_the_robots_private_paths(tmp_path: Path, path: str, private: bool) -> None:
    root = tmp_path / "root"
    mapped = mountview.host_path(root, path)
    assert mapped.is_relative_to(root) == private
    assert mountview.is_private(path) == private


def test_a_host_folder_is_never_shared_into_a_robot(tmp_path: Path) -> None:
    """Mounting over a path the host owns would hide that folder from the robot's node processes."""
    with pytest.raises(mountview.MountError, match=r"/etc/maps is not a robot's own path"):
        mountview.bind_into(tmp_path / "ns", tmp_path / "root", tmp_path / "share", "/etc/maps")
    assert not (tmp_path / "root").exists()


def test_local_image_archive_is_a_valid_oci_layout_and_reproducible() -> None:
    archive = nodeimages.build_archive(b"\x7fELF fake busybox", nodeimages.LOCAL_IMAGES)
    assert archive == nodeimages.build_archive(b"\x7fELF fake busybox", nodeimages.LOCAL_IMAGES)
    with tarfile.open(fileobj=io.BytesIO(archive)) as tar:
        members = {m.name: tar.extractfile(m).read() for m in tar.getmembers() if m.isfile()}  # type: ignore[union-attr]
    index = json.loads(members["index.json"])
    assert [m["annotations"]["io.containerd.image.name"] for m in index["manifests"]] == list(
        nodeimages.LOCAL_IMAGES
    )
    for name, data in members.items():
        if name.startswith("blobs/sha256/"):
            assert hashlib.sha256(data).hexdigest() == name.rsplit("/", 1)[1]
    manifest = json.loads(members[f"blobs/sha256/{index['manifests'][0]['digest'].split(':')[1]}"])
    layer = gzip.decompress(members[f"blobs/sha256/{manifest['layers'][0]['digest'].split(':')[1]}"])
    config = json.loads(members[f"blobs/sha256/{manifest['config']['digest'].split(':')[1]}"])
    assert config["rootfs"]["diff_ids"] == [f"sha256:{hashlib.sha256(layer).hexdigest()}"]
    with tarfile.open(fileobj=io.BytesIO(layer)) as files:
        assert files.getmember("bin/sh").linkname == "busybox"


def test_kubectl_wide_tables_are_read_by_column_position() -> None:
    table = (
        "NAME      STATUS   OS-IMAGE                         CONTAINER-RUNTIME\n"
        "robot-1   Ready    Debian GNU/Linux 12 (bookworm)   containerd://1.6.20\n"
        "kwok-1    Ready    <unknown>                        kwok-0.7.0\n"
    )
    rows = parse_table(table)
    assert rows["robot-1"]["OS-IMAGE"] == "Debian GNU/Linux 12 (bookworm)"
    assert rows["robot-1"]["CONTAINER-RUNTIME"] == "containerd://1.6.20"
    assert rows["kwok-1"]["CONTAINER-RUNTIME"] == "kwok-0.7.0"
