"""Files and command lines of one real robot (kubelet, containerd, CNI, registry hosts), as pure functions.

`realrobots` writes them into the robot's folder and starts the processes. Every path a process
sees is either in the robot's folder (absolute host paths) or one of `mountview.PRIVATE`, which
the robot's mount view binds to its folder too.
"""

from __future__ import annotations

import json
import os
import shutil
import sys
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import yaml
from coral_core import offline

from coral_testbed.cluster import kubeconfigs, mountview, nodeimages, robotnet
from coral_testbed.cluster.paths import Under

KUBELET_PORT = 10250
KUBELET_HEALTHZ_PORT = 10248
DEFAULT_REGISTRY = "127.0.0.1:5000"
REGISTRY_ENV = "CORAL_REGISTRY"
# Image names for robots; containerd maps this host name to the local registry.
REGISTRY_NAME = "coral.local"
DOCKER_HUB = "docker.io"
DOCKER_HUB_ENDPOINT = "registry-1.docker.io"
CNI_BIN_DIR = "/usr/lib/cni"
CONTAINERD_SOCKET = "/run/containerd/containerd.sock"


def registry_address() -> str:
    """host:port of the local registry on the host's loopback (`$CORAL_REGISTRY`, default 127.0.0.1:5000).

    Raises:
        ValueError: the value is not 127.0.0.1:PORT.
    """
    value = os.environ.get(REGISTRY_ENV, DEFAULT_REGISTRY)
    host, _, port = value.rpartition(":")
    if host != "127.0.0.1" or not port.isdigit() or not 0 < int(port) < 65536:
        raise ValueError(f"${REGISTRY_ENV}={value!r}: give the local registry as 127.0.0.1:PORT")
    return value


@dataclass(frozen=True)
class RobotLayout:
    """Everything one robot's files and command lines depend on."""

    name: str
    slot: int
    index: int
    dir: Path
    bin_dir: Path
    api_port: int
    registry: str
    ca_cert: Path

    @property
    def link(self) -> robotnet.RobotLink:
        return robotnet.RobotLink(self.name, self.slot, self.index)

    @property
    def root(self) -> Path:
        """Host folder behind the robot's private paths (mountview.PRIVATE)."""
        return self.dir / "root"

    @property
    def ns_file(self) -> Path:
        return self.dir.parent / ".ns" / f"{self.name}.mnt"

    @property
    def cgroup_root(self) -> str:
        return f"/coral-{self.slot}-{self.name}"

    @property
    def runtime_cgroup(self) -> str:
        return f"{self.cgroup_root}/runtime"

    @property
    def registry_port(self) -> int:
        return int(self.registry.rpartition(":")[2])

    containerd_config = Under("dir", "containerd.toml")
    cni_conf_dir = Under("dir", "cni", "net.d")
    registry_hosts_dir = Under("dir", "certs.d")
    kubelet_config = Under("dir", "kubelet.yaml")
    kubelet_kubeconfig = Under("dir", "kubelet.kubeconfig")

    @property
    def image_cache(self) -> Path:
        return self.dir.parent / ".images"

    def to_json(self) -> dict[str, Any]:
        data = asdict(self)
        return {**data, "dir": str(self.dir), "bin_dir": str(self.bin_dir), "ca_cert": str(self.ca_cert)}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> RobotLayout:
        return cls(
            **{
                **data,
                "dir": Path(data["dir"]),
                "bin_dir": Path(data["bin_dir"]),
                "ca_cert": Path(data["ca_cert"]),
            }
        )


def enter_robot(layout: RobotLayout) -> list[str]:
    """What to put before a command so it runs in the robot's network, mount view and host name."""
    nsenter = shutil.which("nsenter") or "/usr/bin/nsenter"
    return [
        nsenter,
        f"--net={layout.link.netns_path}",
        f"--mount={layout.ns_file}",
        f"--uts={mountview.uts_file(layout.ns_file)}",
        "--",
    ]


def build_containerd_config(layout: RobotLayout) -> str:
    """containerd's config (TOML, version 2); root and state are private paths of the robot."""
    cri = 'plugins."io.containerd.grpc.v1.cri"'
    lines = [
        "version = 2",
        'root = "/var/lib/containerd"',
        'state = "/run/containerd"',
        "oom_score = 0",
        "[grpc]",
        f'  address = "{CONTAINERD_SOCKET}"',
        "[ttrpc]",
        '  address = ""',
        "[debug]",
        '  address = ""',
        "[metrics]",
        '  address = ""',
        f"[{cri}]",
        f'  sandbox_image = "{nodeimages.SANDBOX_IMAGE}"',
        # Without CAP_SYS_RESOURCE runc cannot lower oom_score_adj: sandboxes would fail with
        # "can't get final child's PID from pipe: EOF".
        "  restrict_oom_score_adj = true",
        # Pod network namespaces are mounted under the robot's private /run/containerd.
        "  netns_mounts_under_state_dir = true",
        "  disable_apparmor = true",
        '  stream_server_address = "127.0.0.1"',
        '  stream_server_port = "0"',
        f"[{cri}.containerd]",
        '  snapshotter = "overlayfs"',
        '  default_runtime_name = "runc"',
        f"[{cri}.containerd.runtimes.runc]",
        '  runtime_type = "io.containerd.runc.v2"',
        f"[{cri}.containerd.runtimes.runc.options]",
        "  SystemdCgroup = false",
        f"[{cri}.cni]",
        f'  bin_dir = "{CNI_BIN_DIR}"',
        f'  conf_dir = "{layout.cni_conf_dir}"',
        "  max_conf_num = 1",
        f"[{cri}.registry]",
        f'  config_path = "{layout.registry_hosts_dir}"',
    ]
    return "\n".join(lines) + "\n"


def build_registry_hosts(registry: str) -> dict[str, str]:
    """hosts.toml per registry name: `coral.local` and the registry's own address, both plain HTTP,
    and Docker Hub with the registry as its mirror, so the names the examples use as on any cluster
    (`coral/executor:0.1.0`, i.e. docker.io/coral/executor) resolve on robots without Docker Hub."""
    mirror = f'[host."http://{registry}"]\n  capabilities = ["pull", "resolve"]\n  skip_verify = true\n'
    body = f'server = "http://{registry}"\n\n{mirror}'
    hub = f'server = "https://{DOCKER_HUB_ENDPOINT}"\n\n{mirror}'
    return {REGISTRY_NAME: body, registry: body, DOCKER_HUB: hub}


def build_cni_config(layout: RobotLayout) -> dict[str, Any]:
    """A bridge inside the robot for pods off the host network, addresses from the robot's pod subnet."""
    return {
        "cniVersion": "1.0.0",
        "name": "coral-robot",
        "plugins": [
            {
                "type": "bridge",
                "bridge": "cni0",
                "isGateway": True,
                "ipMasq": False,
                "hairpinMode": True,
                "ipam": {
                    "type": "host-local",
                    "ranges": [[{"subnet": robotnet.pod_subnet(layout.slot, layout.index)}]],
                    "routes": [{"dst": "0.0.0.0/0"}],
                    # The default (/var/lib/cni) is shared by every robot on the host.
                    "dataDir": str(layout.dir / "cni" / "ipam"),
                },
            },
        ],
    }


def build_kubelet_config(layout: RobotLayout) -> dict[str, Any]:
    return {
        "apiVersion": "kubelet.config.k8s.io/v1beta1",
        "kind": "KubeletConfiguration",
        "address": layout.link.address,
        "port": KUBELET_PORT,
        "readOnlyPort": 0,
        "healthzBindAddress": "127.0.0.1",
        "healthzPort": KUBELET_HEALTHZ_PORT,
        "authentication": {
            "anonymous": {"enabled": False},
            "webhook": {"enabled": True},
            "x509": {"clientCAFile": str(layout.ca_cert)},
        },
        "authorization": {"mode": "Webhook"},
        # cgroup v1 machines: the kubelet refuses v1 unless told, and there is no systemd here.
        "failCgroupV1": False,
        "cgroupDriver": "cgroupfs",
        "cgroupRoot": layout.cgroup_root,
        "cgroupsPerQOS": True,
        "enforceNodeAllocatable": ["pods"],
        "failSwapOn": False,
        "containerRuntimeEndpoint": f"unix://{CONTAINERD_SOCKET}",
        "imageServiceEndpoint": f"unix://{CONTAINERD_SOCKET}",
        "makeIPTablesUtilChains": False,
        "serializeImagePulls": False,
        "resolvConf": "/etc/resolv.conf",
        # Robots share the host's disk with everything else: evict only when it is really full.
        "evictionHard": {"memory.available": "100Mi", "nodefs.available": "1%", "imagefs.available": "1%"},
        "imageGCHighThresholdPercent": 99,
        "imageGCLowThresholdPercent": 98,
        "nodeStatusUpdateFrequency": "10s",
        "shutdownGracePeriod": "0s",
        "rotateCertificates": False,
        "serverTLSBootstrap": False,
        "registerNode": True,
        # The robot's offline agent writes its last revision here when it boots cut off (docs/offline.md).
        "staticPodPath": offline.STATIC_POD_DIR,
        "fileCheckFrequency": "2s",
    }


def build_kubelet_kubeconfig(layout: RobotLayout, client_cert: Path, client_key: Path) -> dict[str, Any]:
    # The uplink offers the API server at its host address inside the robot.
    return kubeconfigs.build_kubeconfig(
        server=f"https://127.0.0.1:{layout.api_port}",
        ca_cert=layout.ca_cert,
        client_cert=client_cert,
        client_key=client_key,
        user=f"system:node:{layout.name}",
    )


def build_containerd(layout: RobotLayout) -> list[str]:
    return [
        *enter_robot(layout),
        shutil.which("containerd") or "containerd",
        f"--config={layout.containerd_config}",
    ]


def build_kubelet(layout: RobotLayout, labels: dict[str, str]) -> list[str]:
    node_labels = ",".join(f"{key}={value}" for key, value in sorted(labels.items()))
    label_flags = [f"--node-labels={node_labels}"] if node_labels else []
    return [
        *enter_robot(layout),
        str(layout.bin_dir / "kubelet"),
        f"--config={layout.kubelet_config}",
        f"--kubeconfig={layout.kubelet_kubeconfig}",
        f"--hostname-override={layout.name}",
        f"--node-ip={layout.link.address}",
        *label_flags,
        "--root-dir=/var/lib/kubelet",
        f"--cert-dir={layout.dir / 'kubelet-pki'}",
        "--v=1",
    ]


def build_offline_agent(layout: RobotLayout, step: str) -> list[str]:
    """The robot's offline agent: `boot` (once, before the kubelet) or `watch` (beside it)."""
    return [
        *enter_robot(layout),
        sys.executable,
        "-m",
        "coral.offline",
        step,
        f"--robot={layout.name}",
        f"--kubeconfig={layout.kubelet_kubeconfig}",
    ]


def build_uplink(layout: RobotLayout) -> list[str]:
    return [
        sys.executable,
        "-m",
        "coral_testbed.cluster.uplink",
        str(layout.link.netns_path),
        str(layout.api_port),
        str(layout.registry_port),
    ]


def build_ctr(layout: RobotLayout) -> list[str]:
    return [*enter_robot(layout), shutil.which("ctr") or "ctr", "--address", CONTAINERD_SOCKET]


def build_cri(layout: RobotLayout) -> list[str]:
    endpoint = f"unix://{CONTAINERD_SOCKET}"
    return [
        *enter_robot(layout),
        str(layout.bin_dir / "crictl"),
        f"--runtime-endpoint={endpoint}",
        f"--image-endpoint={endpoint}",
    ]


def write_files(layout: RobotLayout, client_cert: Path, client_key: Path) -> None:
    layout.dir.mkdir(parents=True, exist_ok=True)
    layout.containerd_config.write_text(build_containerd_config(layout))
    layout.cni_conf_dir.mkdir(parents=True, exist_ok=True)
    (layout.cni_conf_dir / "10-coral-robot.conflist").write_text(
        json.dumps(build_cni_config(layout), indent=2)
    )
    for host, body in build_registry_hosts(layout.registry).items():
        folder = layout.registry_hosts_dir / host
        folder.mkdir(parents=True, exist_ok=True)
        (folder / "hosts.toml").write_text(body)
    layout.kubelet_config.write_text(yaml.safe_dump(build_kubelet_config(layout), sort_keys=False))
    kubeconfigs.write_kubeconfig(
        layout.kubelet_kubeconfig, build_kubelet_kubeconfig(layout, client_cert, client_key)
    )
