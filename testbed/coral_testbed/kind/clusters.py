"""kind clusters of robots: create, find and delete them, with their network and image registry.

A cluster is one kind control plane and one kind worker per robot, labelled
`coral.dev/robot=<name>` (the label contract: docs/kind.md). Each cluster gets, besides what kind
makes:

- its own Docker network (`coral-kind-<cluster>`, a /24 the host uses nowhere else), so that a
  robot's link can be cut (`docker network disconnect`) and restored at the same address;
- the project's image registry (Debian's docker-registry over the checkout's registry storage,
  `coral_testbed.images.registry`) listening on that network's gateway, which every node's
  containerd uses as the mirror of `docker.io` and `coral.local` (kind's local-registry pattern
  with a registry process instead of a container): `coral/executor:0.1.0` pulls from it;
- optionally kwok, against kind's API server, for simulated robots at fleet scale;
- the robot's offline agent on every robot, installed as a robot's owner installs it (`offlineagent`).

State (kubeconfig, registry and kwok records, logs) lives in
`~/.cache/coral-on-kubernetes/kind/clusters/<name>/`. Called by the CLI, the demo and the tests.
"""

from __future__ import annotations

import ipaddress
import json
import shutil
import subprocess
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from coral_testbed import images
from coral_testbed.cluster import binaries, components, controlplane
from coral_testbed.images import registry
from coral_testbed.kind import engine, offlineagent

ROBOT_LABEL = "coral.dev/robot"
KIND_VERSION = "v0.33.0"
"""The kind release hack/build-kind-tools.sh builds (its KIND_VERSION)."""
DEFAULT_NAME = "coral"
KIND_CLUSTER_LABEL = "io.x-k8s.kind.cluster"
"""The label kind puts on every node container of a cluster."""
_SUBNETS = ipaddress.ip_network("10.89.0.0/16")
"""Where clusters' networks are carved from: clear of kind's pod (10.244/16) and Service (10.96/12) ranges."""
_KUBEADM_FIELDS = {
    "kube-apiserver": "apiServer",
    "kube-controller-manager": "controllerManager",
    "kube-scheduler": "scheduler",
}
"""Control-plane component -> its section of kubeadm's ClusterConfiguration."""
_ARGS_UNSET = frozenset({"scheduler"})
"""Sections whose extraArgs kind v0.33's template leaves empty (null, without feature gates): set
whole. The others hold kind's own flags, beside which the benchmark's are added."""
KUBEADM_API = "v1beta3"
"""The kubeadm configuration kind v0.33 writes for the node image's Kubernetes 1.34: it renders
v1beta4 only from 1.36 on. A patch naming another version matches nothing and kind drops it silently."""


class ClusterError(RuntimeError):
    """A cluster could not be created, found or deleted; the message says which and why."""


@dataclass(frozen=True)
class ClusterSpec:
    name: str
    robots: dict[str, dict[str, str]]
    """Robot name -> its further labels (`coral.dev/model`, ...); one kind worker each."""
    node_image: str
    registry_address: str
    """HOST:PORT of the registry on the cluster's network gateway."""
    extra_workers: dict[str, dict[str, str]] = field(default_factory=dict)
    """Non-robot workers (the operator's node, say): name -> labels."""
    robot_mounts: dict[str, str] = field(default_factory=dict)
    """Path in every robot's node -> the host folder bound there: a site share all robots see."""
    control_plane_args: Mapping[str, Sequence[str]] = field(default_factory=dict)
    """More flags per control-plane component (`kube-apiserver`: ["--audit-log-path=..."], ...)."""
    apiserver_folders: tuple[str, ...] = ()
    """Host folders the API server sees at the same path (its audit policy and log, say)."""
    heartbeats: components.Heartbeats | None = None
    """The robots' Lease length and how soon a silent one turns Unknown; None leaves kind's."""


def _control_plane_args(spec: ClusterSpec) -> dict[str, list[str]]:
    """`spec`'s control-plane flags with those of its heartbeats. Pure."""
    args = {component: list(flags) for component, flags in spec.control_plane_args.items()}
    if spec.heartbeats:
        manager = args.setdefault("kube-controller-manager", [])
        manager += spec.heartbeats.controller_manager_flags()
    return args


def _kubeadm_patches(spec: ClusterSpec) -> list[dict[str, str]]:
    """JSON 6902 patches of kubeadm's ClusterConfiguration adding `spec`'s flags and folders, and of
    the KubeletConfiguration every node's kubelet reads its Lease length from. Pure."""
    patches: list[dict[str, str]] = []
    if spec.heartbeats:
        lease = [{"op": "add", "path": "/nodeLeaseDurationSeconds", "value": spec.heartbeats.lease_s}]
        patches.append(
            {
                "group": "kubelet.config.k8s.io",
                "version": "v1beta1",
                "kind": "KubeletConfiguration",
                "patch": json.dumps(lease),
            }
        )
    ops: list[dict[str, object]] = []
    for component, flags in sorted(_control_plane_args(spec).items()):
        section = _KUBEADM_FIELDS[component]
        # v1beta3's extraArgs is a map of flag name to value.
        args = {name: value for name, _, value in (f.removeprefix("--").partition("=") for f in flags)}
        if section in _ARGS_UNSET:
            ops.append({"op": "add", "path": f"/{section}/extraArgs", "value": args})
        else:
            ops += [{"op": "add", "path": f"/{section}/extraArgs/{k}", "value": v} for k, v in args.items()]
    if spec.apiserver_folders:
        volumes = [
            {"name": f"coral-{i}", "hostPath": folder, "mountPath": folder, "pathType": "DirectoryOrCreate"}
            for i, folder in enumerate(spec.apiserver_folders)
        ]
        ops.append({"op": "add", "path": "/apiServer/extraVolumes", "value": volumes})
    if ops:
        patches.append(
            {
                "group": "kubeadm.k8s.io",
                "version": KUBEADM_API,
                "kind": "ClusterConfiguration",
                "patch": json.dumps(ops),
            }
        )
    return patches


def build_config(spec: ClusterSpec) -> str:
    """kind's cluster configuration (JSON, which kind reads as YAML) for `spec`. Pure."""
    mirror = f"http://{spec.registry_address}"
    patch = "\n".join(
        f'[plugins."io.containerd.grpc.v1.cri".registry.mirrors."{host}"]\n  endpoint = ["{mirror}"]'
        for host in ("docker.io", "coral.local", spec.registry_address)
    )
    control_plane: dict[str, object] = {"role": "control-plane"}
    if spec.apiserver_folders:
        control_plane["extraMounts"] = [{"hostPath": f, "containerPath": f} for f in spec.apiserver_folders]
    nodes: list[dict[str, object]] = [control_plane]
    mounts = [{"hostPath": host, "containerPath": path} for path, host in sorted(spec.robot_mounts.items())]
    for robot, labels in spec.robots.items():
        node: dict[str, object] = {"role": "worker", "labels": {**labels, ROBOT_LABEL: robot}}
        if mounts:
            node["extraMounts"] = mounts
        nodes.append(node)
    for labels in spec.extra_workers.values():
        nodes.append({"role": "worker", "labels": dict(labels)})
    config: dict[str, object] = {
        "kind": "Cluster",
        "apiVersion": "kind.x-k8s.io/v1alpha4",
        "name": spec.name,
        "nodes": nodes,
        "containerdConfigPatches": [patch],
    }
    patches = _kubeadm_patches(spec)
    if patches:
        config["kubeadmConfigPatchesJSON6902"] = patches
    return json.dumps(config, indent=2)


_NETWORK_ATTEMPTS = 5


def free_subnet(taken: list[str]) -> ipaddress.IPv4Network:
    """The first /24 of 10.89.0.0/16 overlapping none of `taken` (CIDRs in use on the host). Pure."""
    used = [ipaddress.ip_network(cidr, strict=False) for cidr in taken]
    for candidate in _SUBNETS.subnets(new_prefix=24):
        if not any(candidate.overlaps(other) for other in used if other.version == 4):
            return candidate  # type: ignore[return-value]
    raise ClusterError(f"no free /24 left in {_SUBNETS} for a kind network")


def state_dir(name: str) -> Path:
    return binaries.cache_root() / "kind" / "clusters" / name


def network_name(name: str) -> str:
    return f"coral-kind-{name}"


def kind_binary() -> Path:
    """kind, built by hack/build-kind-tools.sh (`coral dev-cluster setup`)."""
    # The tools' folder is keyed by every version hack/build-kind-tools.sh pins, kind's first.
    found = sorted((binaries.cache_root() / "kind" / "tools").glob(f"kind-{KIND_VERSION}_*/bin/kind"))
    if found:
        return found[-1]
    on_path = shutil.which("kind")
    if on_path is None:
        raise ClusterError("kind is not built yet; run `coral dev-cluster setup` (or `make kind`)")
    return Path(on_path)


def _host_cidrs(node_engine: engine.Engine) -> list[str]:
    routes = subprocess.run(["ip", "-4", "route", "show"], capture_output=True, text=True).stdout
    cidrs = [line.split()[0] for line in routes.splitlines() if "/" in line.split()[0]]
    networks = node_engine.docker("network", "ls", "-q").stdout.split()
    if networks:
        inspected = json.loads(node_engine.docker("network", "inspect", *networks).stdout)
        cidrs += [
            config["Subnet"] for net in inspected for config in (net.get("IPAM", {}).get("Config") or [])
        ]
    return cidrs


def create_network(node_engine: engine.Engine, name: str) -> ipaddress.IPv4Network:
    """The cluster's Docker network (created if missing); returns its subnet."""
    network = network_name(name)
    existing = node_engine.docker("network", "inspect", network, check=False)
    if existing.returncode == 0:
        return ipaddress.ip_network(json.loads(existing.stdout)[0]["IPAM"]["Config"][0]["Subnet"])  # type: ignore[return-value]
    refused: list[str] = []
    # Two clusters made at once (the tests' two lanes) may both find the same /24 free: the second
    # `network create` is refused, and the next free one is tried.
    for _ in range(_NETWORK_ATTEMPTS):
        subnet = free_subnet(_host_cidrs(node_engine) + refused)
        made = node_engine.docker(
            "network",
            "create",
            "--driver=bridge",
            f"--subnet={subnet}",
            f"--gateway={subnet[1]}",
            "--opt=com.docker.network.driver.mtu=1500",
            network,
            check=False,
        )
        if made.returncode == 0:
            return subnet
        if "overlaps" not in made.stderr:
            raise engine.EngineError(f"docker network create {network} failed: {made.stderr.strip()}")
        refused.append(str(subnet))
    raise ClusterError(f"docker network create {network}: every subnet tried overlapped another ({refused})")


@dataclass(frozen=True)
class Running:
    """A created cluster: where its kubeconfig is and how to reach its nodes."""

    name: str
    kubeconfig: Path
    engine: engine.Engine
    registry_address: str

    def node_containers(self) -> list[str]:
        return sorted(self.engine.containers(f"{KIND_CLUSTER_LABEL}={self.name}"))

    def env(self) -> dict[str, str]:
        return {**self.engine.env(), "KUBECONFIG": str(self.kubeconfig)}


def _record(name: str) -> Path:
    return state_dir(name) / "cluster.json"


def load(name: str, node_engine: engine.Engine) -> Running | None:
    """The cluster `create` made under `name`, if its record and its nodes still exist."""
    try:
        data = json.loads(_record(name).read_text())
    except (OSError, ValueError):
        return None
    running = Running(name, Path(data["kubeconfig"]), node_engine, data["registry"])
    return running if running.node_containers() else None


def start_registry(name: str, subnet: ipaddress.IPv4Network) -> str:
    """The checkout's registry storage served on the cluster network's gateway; its address."""
    address = registry.free_address(str(subnet[1]))
    registry.up(address, images.registry_storage(), state_dir(name))
    return address


def create(
    name: str,
    robots: dict[str, dict[str, str]],
    node_engine: engine.Engine,
    node_image: str,
    progress: Callable[[str], None],
    extra_workers: dict[str, dict[str, str]] | None = None,
    robot_mounts: dict[str, str] | None = None,
    control_plane_args: Mapping[str, Sequence[str]] | None = None,
    apiserver_folders: Sequence[str] = (),
    heartbeats: components.Heartbeats | None = None,
) -> Running:
    """Creates the kind cluster `name` with one worker per robot and waits until every node is Ready.
    `robot_mounts` (path in the node -> host folder) are bound into every robot's node;
    `control_plane_args`, `apiserver_folders` and `heartbeats` as `ClusterSpec`'s.

    Raises:
        ClusterError, engine.EngineError: naming the step and the log to read.
    """
    # Until its first node container exists nothing on the engine shows that this run needs it.
    with engine.kept_running(node_engine, progress):
        folder = state_dir(name)
        folder.mkdir(parents=True, exist_ok=True)
        log = folder / "kind.log"
        subnet = create_network(node_engine, name)
        address = start_registry(name, subnet)
        progress(
            f"registry for the cluster's nodes on {address} (the network {network_name(name)}'s gateway)"
        )
        spec = ClusterSpec(
            name,
            robots,
            node_image,
            address,
            extra_workers or {},
            robot_mounts or {},
            control_plane_args or {},
            tuple(apiserver_folders),
            heartbeats,
        )
        config = folder / "kind-config.json"
        config.write_text(build_config(spec))
        kubeconfig = folder / "kubeconfig"
        workers = len(robots) + len(extra_workers or {})
        progress(
            f"kind create cluster --name {name}: a control plane, {workers} workers ({len(robots)} robots)"
        )
        progress(f"  (log {log})")
        argv = [
            str(kind_binary()),
            "create",
            "cluster",
            "--name",
            name,
            "--image",
            node_image,
            "--config",
            str(config),
            "--kubeconfig",
            str(kubeconfig),
            "--wait",
            "5m",
        ]
        # kind joins the nodes to the network named here rather than making its own `kind` network.
        env = {
            **node_engine.env(),
            "KIND_EXPERIMENTAL_DOCKER_NETWORK": network_name(name),
            "KIND_EXPERIMENTAL_PROVIDER": "docker",
        }
        with log.open("a") as sink:
            done = subprocess.run(argv, env=env, stdout=sink, stderr=subprocess.STDOUT)
        if done.returncode != 0:
            raise ClusterError(f"kind create cluster failed (exit {done.returncode}); see {log}")
        _record(name).write_text(json.dumps({"kubeconfig": str(kubeconfig), "registry": address}))
        # kind's --wait covers the control plane; robots are Ready once their pod network is written.
        waited = subprocess.run(
            [
                binaries.find_kubectl(None),
                "wait",
                "--for=condition=Ready",
                "nodes",
                "--all",
                "--timeout=180s",
            ],
            env={**env, "KUBECONFIG": str(kubeconfig)},
            capture_output=True,
            text=True,
        )
        if waited.returncode != 0:
            raise ClusterError(
                f"the nodes of kind cluster {name} did not become Ready: {waited.stderr.strip()}"
            )
        running = Running(name, kubeconfig, node_engine, address)
        if robots:
            progress("  the offline agent on every robot (deploy/robot/, docs/offline.md)")
            offlineagent.install(node_engine, robot_nodes(running))
        return running


def robot_nodes(running: Running) -> list[str]:
    """The node containers of the cluster's robots (the Nodes labelled `coral.dev/robot`)."""
    done = subprocess.run(
        [binaries.find_kubectl(None), "get", "nodes", "-l", ROBOT_LABEL, "-o", "name"],
        env=running.env(),
        capture_output=True,
        text=True,
        timeout=60,
    )
    if done.returncode != 0:
        raise ClusterError(f"the robots of kind cluster {running.name}: {done.stderr.strip()}")
    return [line.removeprefix("node/") for line in done.stdout.split()]


def load_image_archive(running: Running, archive: Path) -> None:
    """`kind load image-archive` of `archive` (a docker or OCI archive) into every node's containerd,
    under the names the archive gives its images: what a user does with an image no registry holds.

    Raises:
        ClusterError: naming the archive and kind's error.
    """
    done = subprocess.run(
        [str(kind_binary()), "load", "image-archive", str(archive), "--name", running.name],
        env={**running.engine.env(), "KIND_EXPERIMENTAL_PROVIDER": "docker"},
        capture_output=True,
        text=True,
        timeout=300,
    )
    if done.returncode != 0:
        raise ClusterError(f"kind load image-archive {archive} failed: {done.stderr.strip()}")


def kwok_dir(name: str) -> Path:
    return state_dir(name) / "kwok"


def start_kwok(running: Running, extra_args: Sequence[str] = ()) -> controlplane.State:
    """kwok against the cluster's API server, so simulated robots (kwok Nodes) join it."""
    return controlplane.start_kwok(kwok_dir(running.name), running.kubeconfig, extra_args=extra_args)


def delete(name: str, node_engine: engine.Engine, progress: Callable[[str], None]) -> None:
    """Deletes the cluster, its kwok, its registry process and its network; a no-op for what is gone."""
    folder = state_dir(name)
    controlplane.stop(kwok_dir(name))
    if node_engine.containers(f"{KIND_CLUSTER_LABEL}={name}"):
        progress(f"kind delete cluster --name {name}")
        done = subprocess.run(
            [str(kind_binary()), "delete", "cluster", "--name", name],
            env=node_engine.env(),
            capture_output=True,
            text=True,
        )
        if done.returncode != 0:
            raise ClusterError(f"kind delete cluster --name {name} failed: {done.stderr.strip()}")
    for address in registry.recorded_addresses(folder):
        registry.down(folder, address)
    node_engine.docker("network", "rm", network_name(name), check=False)
    _record(name).unlink(missing_ok=True)
    # A kubeconfig of a deleted cluster would only point the next `export KUBECONFIG` nowhere.
    (folder / "kubeconfig").unlink(missing_ok=True)


def stop_engine_unless_used(node_engine: engine.Engine) -> bool:
    """Stops the project's dockerd unless another kind cluster still runs on it (another user's or
    test's); True when it was stopped. Called after each cluster is deleted, whichever run started
    the engine: of two runs that overlap, the one started first may end first, and the engine must
    stop with the last cluster, not with the run that happened to start it. A user's Docker
    (`$CORAL_DOCKER_HOST`) is never stopped."""
    if not node_engine.owned:
        return False
    return engine.stop_unless(lambda: runs_a_cluster(node_engine))


def runs_a_cluster(node_engine: engine.Engine) -> bool:
    """Whether any kind cluster (any name, running or stopped) has node containers on the engine."""
    return bool(node_engine.containers(KIND_CLUSTER_LABEL))
