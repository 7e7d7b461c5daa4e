"""The pure parts of the kind tooling: cluster configuration, network choice, the pod network's
manifest, preloaded image archives and the runtime wrapper's capability filter."""

from __future__ import annotations

import hashlib
import io
import ipaddress
import json
import runpy
import tarfile
from pathlib import Path

import jsonpatch
import pytest
import yaml
from coral_testbed.cluster import components
from coral_testbed.kind import clusters, imagearchives, kindnet, offlineagent

REPOSITORY = Path(__file__).resolve().parents[3]


def _spec(**overrides: object) -> clusters.ClusterSpec:
    values: dict[str, object] = {
        "name": "coral",
        "robots": {"robot-1": {"coral.dev/model": "tb4"}, "robot-2": {}},
        "node_image": "coral.local/kind-node:v1.34.4-abc",
        "registry_address": "10.89.0.1:5000",
    }
    values.update(overrides)
    return clusters.ClusterSpec(**values)  # type: ignore[arg-type]


def test_each_robot_is_a_worker_labelled_with_its_name_after_one_control_plane() -> None:
    config = yaml.safe_load(clusters.build_config(_spec()))
    roles = [node["role"] for node in config["nodes"]]
    assert roles == ["control-plane", "worker", "worker"]
    assert config["nodes"][1]["labels"] == {"coral.dev/model": "tb4", "coral.dev/robot": "robot-1"}
    assert config["nodes"][2]["labels"] == {"coral.dev/robot": "robot-2"}


def test_a_non_robot_worker_carries_only_its_own_labels() -> None:
    config = yaml.safe_load(
        clusters.build_config(_spec(extra_workers={"ops": {"coral.dev/operator-node": "true"}}))
    )
    assert config["nodes"][-1] == {"role": "worker", "labels": {"coral.dev/operator-node": "true"}}


def test_a_site_share_is_bound_into_every_robot_and_no_other_node() -> None:
    spec = _spec(robot_mounts={"/srv/maps": "/tmp/share"}, extra_workers={"ops": {}})
    nodes = yaml.safe_load(clusters.build_config(spec))["nodes"]
    share = [{"hostPath": "/tmp/share", "containerPath": "/srv/maps"}]
    assert [node.get("extraMounts") for node in nodes] == [None, share, share, None]


# What kind v0.33 generates for kubeadm 1.34 without feature gates, as its template
# (ConfigTemplateBetaV3, which it renders below Kubernetes 1.36) reads: the sections the patches reach.
_KIND_CLUSTER_CONFIGURATION = {
    "apiVersion": "kubeadm.k8s.io/v1beta3",
    "kind": "ClusterConfiguration",
    "apiServer": {"certSANs": ["localhost"], "extraArgs": {"runtime-config": ""}},
    "controllerManager": {"extraArgs": {"enable-hostpath-provisioner": "true"}},
    "scheduler": {"extraArgs": None},
}


def test_control_plane_flags_and_folders_reach_kubeadm_beside_kinds_own() -> None:
    spec = _spec(
        control_plane_args={
            "kube-apiserver": ["--audit-log-path=/tmp/audit/audit.log"],
            "kube-controller-manager": ["--kube-api-qps=500", "--node-monitor-grace-period=300s"],
            "kube-scheduler": ["--kube-api-burst=1000"],
        },
        apiserver_folders=("/tmp/audit",),
    )
    config = yaml.safe_load(clusters.build_config(spec))
    (patch,) = config["kubeadmConfigPatchesJSON6902"]
    # kind applies a patch only to the document of exactly this apiVersion and kind, else drops it.
    assert (f"{patch['group']}/{patch['version']}", patch["kind"]) == (
        _KIND_CLUSTER_CONFIGURATION["apiVersion"],
        _KIND_CLUSTER_CONFIGURATION["kind"],
    )
    patched = jsonpatch.apply_patch(_KIND_CLUSTER_CONFIGURATION, yaml.safe_load(patch["patch"]))
    assert patched["apiServer"]["extraArgs"] == {
        "runtime-config": "",
        "audit-log-path": "/tmp/audit/audit.log",
    }
    assert patched["controllerManager"]["extraArgs"] == {
        "enable-hostpath-provisioner": "true",
        "kube-api-qps": "500",
        "node-monitor-grace-period": "300s",
    }
    assert patched["scheduler"]["extraArgs"] == {"kube-api-burst": "1000"}
    (volume,) = patched["apiServer"]["extraVolumes"]
    assert (volume["hostPath"], volume["mountPath"]) == ("/tmp/audit", "/tmp/audit")
    assert config["nodes"][0]["extraMounts"] == [{"hostPath": "/tmp/audit", "containerPath": "/tmp/audit"}]
    assert all("extraMounts" not in node for node in config["nodes"][1:])


def test_heartbeats_set_every_kubelets_lease_and_the_controllers_grace_beside_other_flags() -> None:
    beats = components.Heartbeats(lease_s=12, grace_s=14, monitor_period_s=1, taints_per_s=1.0)
    spec = _spec(heartbeats=beats, control_plane_args={"kube-controller-manager": ["--kube-api-qps=500"]})
    patches = yaml.safe_load(clusters.build_config(spec))["kubeadmConfigPatchesJSON6902"]
    by_kind = {(f"{p['group']}/{p['version']}", p["kind"]): yaml.safe_load(p["patch"]) for p in patches}
    # kind's template writes this KubeletConfiguration, which kubeadm uploads for every node's kubelet.
    kubelet = jsonpatch.apply_patch(
        {"cgroupDriver": "systemd"}, by_kind[("kubelet.config.k8s.io/v1beta1", "KubeletConfiguration")]
    )
    assert kubelet == {"cgroupDriver": "systemd", "nodeLeaseDurationSeconds": 12}
    cluster = jsonpatch.apply_patch(
        _KIND_CLUSTER_CONFIGURATION,
        by_kind[(_KIND_CLUSTER_CONFIGURATION["apiVersion"], _KIND_CLUSTER_CONFIGURATION["kind"])],
    )
    assert cluster["controllerManager"]["extraArgs"] == {
        "enable-hostpath-provisioner": "true",
        "kube-api-qps": "500",
        "node-monitor-grace-period": "14s",
        "node-monitor-period": "1s",
        "node-eviction-rate": "1.0",
    }


def test_without_control_plane_settings_kubeadm_is_left_as_kind_makes_it() -> None:
    config = yaml.safe_load(clusters.build_config(_spec()))
    assert "kubeadmConfigPatchesJSON6902" not in config
    assert config["nodes"][0] == {"role": "control-plane"}


def test_docker_hub_names_and_coral_local_pull_from_the_clusters_registry() -> None:
    patch = yaml.safe_load(clusters.build_config(_spec()))["containerdConfigPatches"][0]
    for host in ("docker.io", "coral.local", "10.89.0.1:5000"):
        assert f'mirrors."{host}"]\n  endpoint = ["http://10.89.0.1:5000"]' in patch


def test_the_clusters_network_avoids_every_subnet_the_host_uses() -> None:
    chosen = clusters.free_subnet(["10.89.0.0/24", "10.89.1.128/25", "172.17.0.0/16", "fd00::/64"])
    assert chosen == ipaddress.ip_network("10.89.2.0/24")


def test_no_network_is_offered_when_every_candidate_is_taken() -> None:
    with pytest.raises(clusters.ClusterError, match="no free /24"):
        clusters.free_subnet(["10.89.0.0/16"])


def test_the_pod_network_is_a_privileged_host_network_daemonset_kind_patches_with_its_endpoint() -> None:
    manifest = kindnet.build_manifest()
    assert "would you kindly patch this file" in manifest
    documents = {doc["kind"]: doc for doc in yaml.safe_load_all(manifest)}
    pod = documents["DaemonSet"]["spec"]["template"]["spec"]
    assert pod["hostNetwork"] is True
    container = pod["containers"][0]
    # kind appends CONTROL_PLANE_ENDPOINT to this list: it must exist.
    assert [variable["name"] for variable in container["env"]] == ["NODE_NAME"]
    assert container["image"] == kindnet.IMAGE and container["imagePullPolicy"] == "Never"
    assert documents["ClusterRole"]["rules"][0]["resources"] == ["nodes"]


def test_an_archive_image_holds_its_binary_under_the_name_containerd_imports(tmp_path: Path) -> None:
    binary = tmp_path / "etcd"
    binary.write_bytes(b"\x7fELF pretend etcd")
    base = tmp_path / "base.tar"
    with tarfile.open(base, "w") as layer:
        layer.add(str(binary), arcname="etc/base-file")
    archive = tmp_path / "etcd.tar"
    image = imagearchives.ArchiveImage(
        "registry.k8s.io/etcd:3.6.5-0",
        {"/usr/local/bin/etcd": binary},
        base_layers=[base],
        stop_signal="SIGTERM",
    )
    imagearchives.write(image, archive)
    with tarfile.open(archive) as out:
        manifest = json.loads(out.extractfile("manifest.json").read())[0]  # type: ignore[union-attr]
        config = json.loads(out.extractfile(manifest["Config"]).read())  # type: ignore[union-attr]
        layers = [out.extractfile(name).read() for name in manifest["Layers"]]  # type: ignore[union-attr]
    assert manifest["RepoTags"] == ["registry.k8s.io/etcd:3.6.5-0"]
    assert config["rootfs"]["diff_ids"] == [f"sha256:{hashlib.sha256(layer).hexdigest()}" for layer in layers]
    assert config["config"]["StopSignal"] == "SIGTERM"
    top = tarfile.open(fileobj=io.BytesIO(layers[-1]))
    member = top.getmember("usr/local/bin/etcd")
    assert member.mode == 0o755 and top.extractfile(member).read() == binary.read_bytes()  # type: ignore[union-attr]


def test_the_runtime_wrapper_keeps_only_capabilities_of_the_bounding_set(tmp_path: Path) -> None:
    wrapper = runpy.run_path(str(REPOSITORY / "hack" / "runc-within-bounding-set"), run_name="not-main")
    bundle = tmp_path / "bundle"
    bundle.mkdir()
    (bundle / "config.json").write_text(
        json.dumps({"process": {"capabilities": {"bounding": ["CAP_SYS_ADMIN", "CAP_SYS_RESOURCE"]}}})
    )
    found = wrapper["spec_to_trim"](["--root", "/r", "create", "--bundle", str(bundle), "id"])
    wrapper["trim"](*found, {"CAP_SYS_ADMIN"})
    assert json.loads((bundle / "config.json").read_text())["process"]["capabilities"] == {
        "bounding": ["CAP_SYS_ADMIN"]
    }


def test_the_runtime_wrapper_trims_the_process_file_of_a_privileged_exec(tmp_path: Path) -> None:
    wrapper = runpy.run_path(str(REPOSITORY / "hack" / "runc-within-bounding-set"), run_name="not-main")
    process = tmp_path / "process.json"
    process.write_text(
        json.dumps({"args": ["cat"], "capabilities": {"effective": ["CAP_SYS_RESOURCE", "CAP_KILL"]}})
    )
    found = wrapper["spec_to_trim"](["--root", "/r", "exec", "--process", str(process), "--detach", "id"])
    wrapper["trim"](*found, {"CAP_KILL"})
    assert json.loads(process.read_text()) == {"args": ["cat"], "capabilities": {"effective": ["CAP_KILL"]}}
    assert wrapper["spec_to_trim"](["--root", "/r", "delete", "id"]) is None


def _agent() -> dict[str, object]:
    return runpy.run_path(
        str(REPOSITORY / "testbed" / "images" / "kind-net" / "kind_net.py"), run_name="agent"
    )


def test_the_pod_network_routes_to_a_nodes_ipv4_internal_ip_and_never_to_a_kwok_loopback() -> None:
    internal_ip = _agent()["internal_ip"]

    def node(*addresses: str) -> dict[str, object]:
        return {"status": {"addresses": [{"type": "InternalIP", "address": a} for a in addresses]}}

    assert internal_ip(node("fc00::2", "10.89.0.2")) == "10.89.0.2"  # type: ignore[operator]
    assert internal_ip(node("127.0.0.1")) is None  # type: ignore[operator]
    assert internal_ip({"status": {}}) is None  # type: ignore[operator]


def test_a_nodes_cni_config_gives_pods_addresses_of_its_pod_cidr_on_point_to_point_links() -> None:
    config = json.loads(_agent()["conflist"]("10.244.3.0/24"))  # type: ignore[operator]
    main, portmap = config["plugins"]
    assert main["type"] == "ptp" and main["ipam"]["ranges"] == [[{"subnet": "10.244.3.0/24"}]]
    assert portmap["type"] == "portmap"


def test_the_pod_network_stays_off_kwok_robots() -> None:
    documents = {doc["kind"]: doc for doc in yaml.safe_load_all(kindnet.build_manifest())}
    terms = documents["DaemonSet"]["spec"]["template"]["spec"]["affinity"]["nodeAffinity"][
        "requiredDuringSchedulingIgnoredDuringExecution"
    ]["nodeSelectorTerms"]
    assert terms == [{"matchExpressions": [{"key": "type", "operator": "NotIn", "values": ["kwok"]}]}]


def test_the_kind_the_tooling_looks_for_is_the_kind_the_build_script_pins() -> None:
    script = (REPOSITORY / "hack" / "build-kind-tools.sh").read_text()
    assert f'KIND_VERSION="${{KIND_VERSION:-{clusters.KIND_VERSION}}}"' in script


def test_a_robots_offline_agent_gets_its_own_packages_and_what_they_import_and_nothing_else() -> None:
    with tarfile.open(fileobj=io.BytesIO(offlineagent.site_packages())) as tar:
        names = set(tar.getnames())
    for needed in (
        "coral/offline/agent.py",
        "coral_core/offline.py",
        "kubernetes/__init__.py",
        "click/core.py",
    ):
        assert needed in names, needed
    # The robot side beyond the agent stays out, and so do scripts and byte code.
    assert not any(n.startswith(("coral/executor/", "coral_operator/", "coral_testbed/")) for n in names)
    assert not any(n.startswith("..") or n.endswith(".pyc") for n in names)


def test_the_robot_units_run_the_agent_from_its_environment_before_and_beside_the_kubelet() -> None:
    boot, watch = (offlineagent.units_dir() / unit for unit in offlineagent.UNITS)
    boot_text, watch_text = boot.read_text(), watch.read_text()
    assert "Before=kubelet.service" in boot_text and "After=containerd.service" in boot_text
    assert "Type=oneshot" in boot_text and "coral.offline boot" in boot_text
    assert "After=kubelet.service" in watch_text and "Restart=always" in watch_text
    for text in (boot_text, watch_text):
        assert f"ExecStart={offlineagent.PREFIX}/bin/python -m coral.offline" in text
        assert f"CORAL_STATIC_POD_DIR={offlineagent.STATIC_POD_DIR}" in text
