"""The kind node's root filesystem, made as kind's base-image Dockerfile makes it, from what is at hand.

A Debian bookworm root (mmdebstrap) with systemd, containerd, runc, the CNI plugins and the network
tools; kind's node files from its Go module with the changes this machine needs (below); the pinned
kubeadm, kubelet, kubectl and crictl; and a throwaway containerd to preload images into the root's
own store. Called by `nodeimage`, which turns the result into the node image.
"""

from __future__ import annotations

import json
import shutil
import subprocess
from collections.abc import Callable
from pathlib import Path

from coral_testbed.cluster import binaries, processes
from coral_testbed.images import rootfs
from coral_testbed.kind import kindnet
from coral_testbed.waiting import wait_for

PAUSE_TAG = "3.10.1"
NODE_PACKAGES = tuple(
    "systemd containerd runc containernetworking-plugins conntrack iptables nftables iproute2 ethtool "
    "util-linux mount kmod libseccomp2 pigz bash ca-certificates curl jq procps socat python3".split()
)
"""What kind's base image installs, plus python3: a robot's OS ships Python, and the robot's offline
agent (docs/offline.md) runs on it as a host service (`offlineagent`)."""
PROXY_PACKAGES = ("iptables", "conntrack")
"""kube-proxy's image: it runs iptables-restore and conntrack inside its own container."""

# Inside a node: containerd may not raise oom_score_adj (no CAP_SYS_RESOURCE here), pods get the
# pause image kubeadm expects, and the node forwards for its pods (a new network namespace inherits
# the host's ip_forward, which stays 0).
_CONTAINERD_EDITS = {
    "restrict_oom_score_adj = false": "restrict_oom_score_adj = true",
    'sandbox_image = "registry.k8s.io/pause:3.10"': f'sandbox_image = "registry.k8s.io/pause:{PAUSE_TAG}"',
}
_SYSCTL = "# Coral's kind node forwards for its pods; the host's setting stays.\nnet.ipv4.ip_forward=1\n"


class NodeImageError(RuntimeError):
    """The node image could not be built; the message names the step and its log."""


def logged(argv: list[str], log: Path, step: str, **kwargs: object) -> subprocess.CompletedProcess[str]:
    with log.open("a") as sink:
        sink.write(f"$ {' '.join(argv)}\n")
        sink.flush()
        done = subprocess.run(argv, stdout=subprocess.PIPE, stderr=sink, text=True, **kwargs)  # type: ignore[call-overload]
    if done.returncode != 0:
        raise NodeImageError(f"{step} failed (exit {done.returncode}); see {log}")
    return done  # type: ignore[no-any-return]


def make(
    root: Path,
    proxy_base: Path,
    kind_files: Path,
    tools: Path,
    control_plane: Path,
    progress: Callable[[str], None],
    log: Path,
) -> None:
    """The node's root filesystem at `root` (a folder) and kube-proxy's base layer at `proxy_base`."""
    progress(f"  Debian {rootfs.SUITE} root filesystem with {', '.join(NODE_PACKAGES[:7])}, ... (mmdebstrap)")
    debootstrap(root, NODE_PACKAGES, "minbase", log)
    progress(f"  kube-proxy's base: Debian {rootfs.SUITE} with {', '.join(PROXY_PACKAGES)}")
    debootstrap(proxy_base, PROXY_PACKAGES, "essential", log)
    progress("  kind's node files, kubeadm, kubelet, kubectl, crictl, the pod network manifest")
    _install_kind_files(kind_files, root)
    _cri_base_spec(root, log)
    _install_binaries(root, tools, control_plane)
    enable = ["kubelet.service", "containerd.service", "undo-mount-hacks.service"]
    logged(["systemctl", f"--root={root}", "enable", *enable], log, "systemctl enable")
    logged(["systemctl", f"--root={root}", "mask", "systemd-binfmt.service"], log, "systemctl mask")


def debootstrap(target: Path, packages: tuple[str, ...], variant: str, log: Path) -> None:
    argv = ["mmdebstrap", f"--variant={variant}", f"--include={','.join(packages)}"]
    # Merged /usr as bookworm has it (relative links), without the usrmerge package.
    argv.append(f"--hook-dir={rootfs._MERGED_USR_HOOK}")
    argv += [f"--dpkgopt={option}" for option in rootfs._DPKG_OPTIONS]
    logged([*argv, rootfs.SUITE, str(target), *rootfs._sources()], log, f"mmdebstrap of {target.name}")


def _copy_kind_files(kind_files: Path, root: Path) -> None:
    """kind's node files into `root` with the modes kind's Dockerfile gives them (the module cache
    holds them read-only): scripts 0755, the rest 0644."""
    for source in sorted(p for p in kind_files.rglob("*") if p.is_file()):
        inside = source.relative_to(kind_files)
        if inside.parts[0] == "LICENSES":
            continue
        target = root / inside
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(source, target)
        target.chmod(0o755 if inside.parent.name == "bin" else 0o644)


def _install_kind_files(kind_files: Path, root: Path) -> None:
    """What kind's base Dockerfile COPYs and RUNs, from the module's images/base/files."""
    _copy_kind_files(kind_files, root)
    config = root / "etc/containerd/config.toml"
    text = config.read_text()
    for old, new in _CONTAINERD_EDITS.items():
        if old not in text:
            raise NodeImageError(f"kind's containerd config has no {old!r} any more ({config})")
        text = text.replace(old, new)
    config.write_text(text)
    (root / "etc/sysctl.d/99-coral-kind-forwarding.conf").write_text(_SYSCTL)
    # Debian puts containerd in /usr/bin and the CNI plugins in /usr/lib/cni; kind expects
    # /usr/local/bin/containerd and /opt/cni/bin.
    (root / "usr/local/bin/containerd").symlink_to("/usr/bin/containerd")
    (root / "opt/cni").mkdir(parents=True, exist_ok=True)
    (root / "opt/cni/bin").symlink_to("/usr/lib/cni")
    wants = [
        *root.glob("usr/lib/systemd/system/multi-user.target.wants/*"),
        *root.glob("etc/systemd/system/*.wants/*"),
        *root.glob("usr/lib/systemd/system/local-fs.target.wants/*"),
        *root.glob("usr/lib/systemd/system/sockets.target.wants/*udev*"),
        *root.glob("usr/lib/systemd/system/sockets.target.wants/*initctl*"),
        *root.glob("usr/lib/systemd/system/basic.target.wants/*"),
        *root.glob("usr/lib/systemd/system/sysinit.target.wants/systemd-tmpfiles-setup.service"),
    ]
    for link in wants:
        link.unlink()
    with (root / "etc/systemd/journald.conf").open("a") as journald:
        journald.write("ReadKMsg=no\n")
    (root / "usr/sbin/init").unlink(missing_ok=True)
    (root / "usr/sbin/init").symlink_to("/usr/lib/systemd/systemd")
    (root / "etc/kubernetes/manifests").mkdir(parents=True, exist_ok=True)


def _cri_base_spec(root: Path, log: Path) -> None:
    """/etc/containerd/cri-base.json as kind makes it: `ctr oci spec`, plus kind's product-uuid
    hook, minus rlimits (pods inherit the node's)."""
    done = logged(["ctr", "oci", "spec"], log, "ctr oci spec")
    spec = json.loads(done.stdout)
    hooks = spec.setdefault("hooks", {}).setdefault("createContainer", [])
    hooks.append({"path": "/kind/bin/mount-product-files.sh"})
    spec["process"].pop("rlimits", None)
    (root / "etc/containerd/cri-base.json").write_text(json.dumps(spec, indent=2))


def _install_binaries(root: Path, tools: Path, control_plane: Path) -> None:
    for name, folder in (("kubeadm", tools), ("kubelet", control_plane), ("kubectl", control_plane)):
        shutil.copy2(folder / name, root / "usr/bin" / name)
    shutil.copy2(tools / "crictl", root / "usr/local/bin/crictl")
    (root / "kind/version").write_text(binaries.KUBE_VERSION + "\n")
    (root / "kind/manifests").mkdir(parents=True, exist_ok=True)
    (root / "kind/manifests/default-cni.yaml").write_text(kindnet.build_manifest())


def preload(root: Path, archives: list[Path], work: Path, log: Path) -> None:
    """Imports `archives` into the root filesystem's containerd store (namespace k8s.io), with a
    throwaway containerd whose root is that store, as kind's own node-image build does."""
    state = work / "containerd-state"
    socket = work / "containerd.sock"
    config = work / "containerd.toml"
    # Only the content and metadata stores are needed; the CRI plugin would start a pod runtime.
    config.write_text('version = 2\ndisabled_plugins = ["io.containerd.grpc.v1.cri"]\n')
    argv = [
        "containerd",
        "--config",
        str(config),
        "--root",
        str(root / "var/lib/containerd"),
        "--state",
        str(state),
        "--address",
        str(socket),
    ]
    daemon = processes.spawn("containerd-preload", argv, work / "containerd.log")
    try:
        wait_for(socket.exists, timeout=30, message=f"throwaway containerd at {socket}")
        for archive in archives:
            logged(
                [
                    "ctr",
                    "--address",
                    str(socket),
                    "--namespace",
                    "k8s.io",
                    "images",
                    "import",
                    "--no-unpack",
                    "--all-platforms",
                    str(archive),
                ],
                log,
                f"importing {archive.name}",
            )
    finally:
        processes.stop(daemon)
