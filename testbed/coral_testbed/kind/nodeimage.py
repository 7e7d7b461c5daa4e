"""The kind node image: `kindest/node` where it can be pulled, else built here, cached by content.

kind v0.33's own image cannot serve this machine (Kubernetes 1.37 on Debian trixie, whose kubelet
and systemd refuse cgroup v1), and `kind build node-image` needs Docker Hub. So where
`$CORAL_KIND_NODE_IMAGE` names no pullable image, the image is built locally, as kind's base image
Dockerfile does, from what is at hand:

- a Debian bookworm root filesystem (mmdebstrap) with systemd, containerd, runc, the CNI plugins,
  iptables, conntrack and iproute2 from Debian;
- kind's node files (entrypoint, systemd units, containerd config) read from the kind Go module
  in the module cache at build time, never copied into the repository;
- kubeadm, kubelet, kubectl and kube-proxy of the pinned Kubernetes, crictl, and the images kubeadm
  expects (`imagearchives`) plus the pod network (`kindnet`), preloaded into the root filesystem's
  containerd store by a throwaway containerd, so creating a cluster pulls nothing.

The tag carries a hash of every input, so an unchanged recipe is never rebuilt. Called by
`setup` (`coral dev-cluster setup`, `make kind`).
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from coral_testbed import images
from coral_testbed.cluster import binaries
from coral_testbed.images import rootfs
from coral_testbed.kind import clusters, engine, imagearchives, kindnet, noderootfs

IMAGE_ENV = "CORAL_KIND_NODE_IMAGE"
"""A node image to use instead of building one (say `kindest/node:v1.34.3` where it can be pulled)."""
REPOSITORY = "coral.local/kind-node"

ETCD_TAG = "3.6.5-0"
COREDNS_TAG = "v1.12.1"

_TOOLS_SCRIPT = "build-kind-tools.sh"


@dataclass(frozen=True)
class Inputs:
    """Everything the image is made of; `key()` names the image."""

    kind_files: Path
    tools_bin: Path
    control_plane_bin: Path
    kind_net_source: Path
    """The pod network image's folder (Dockerfile, agent): its image is built only with the node's."""

    def key(self) -> str:
        digest = hashlib.sha256()
        for path in [
            Path(__file__),
            Path(noderootfs.__file__),
            Path(kindnet.__file__),
            Path(imagearchives.__file__),
        ]:
            digest.update(path.read_bytes())
        for folder in (self.kind_files, self.kind_net_source):
            for path in sorted(p for p in folder.rglob("*") if p.is_file()):
                digest.update(str(path.relative_to(folder)).encode() + path.read_bytes())
        for folder in (self.tools_bin, self.control_plane_bin):
            for name in sorted(os.listdir(folder)):
                if (folder / name).is_file():
                    digest.update(name.encode() + _file_digest(folder / name))
        digest.update(
            json.dumps([noderootfs.NODE_PACKAGES, noderootfs.PROXY_PACKAGES, rootfs._sources()]).encode()
        )
        return digest.hexdigest()[:16]


def _file_digest(path: Path) -> bytes:
    with path.open("rb") as content:
        return hashlib.file_digest(content, "sha256").digest()


def repository_root() -> Path:
    return images.building.find_repository_root()


def kind_module_dir(log: Path) -> Path:
    """kind's module in the Go module cache (downloaded if missing): its node files are read there."""
    done = noderootfs.logged(
        ["go", "mod", "download", "-json", f"sigs.k8s.io/kind@{clusters.KIND_VERSION}"],
        log,
        "downloading the kind module",
        env={**os.environ, "GOFLAGS": "-mod=mod"},
        cwd=tempfile.gettempdir(),
    )
    return Path(json.loads(done.stdout)["Dir"])


def build_tools(log: Path) -> Path:
    """kind, kubeadm, kube-proxy, crictl, etcd, coredns, pause (hack/build-kind-tools.sh); their folder."""
    script = repository_root() / "hack" / _TOOLS_SCRIPT
    done = noderootfs.logged(["bash", str(script)], log, f"hack/{_TOOLS_SCRIPT}")
    return Path(done.stdout.strip().splitlines()[-1])


def preloaded_images(tools: Path, control_plane: Path, proxy_base: Path) -> list[imagearchives.ArchiveImage]:
    """The images `kubeadm init` and `join` run for Kubernetes 1.34, under the names they expect."""
    kube = binaries.KUBE_VERSION
    archive_images = [
        imagearchives.ArchiveImage(
            f"registry.k8s.io/{name}:{kube}", {f"/usr/local/bin/{name}": control_plane / name}
        )
        for name in ("kube-apiserver", "kube-controller-manager", "kube-scheduler")
    ]
    return [
        *archive_images,
        imagearchives.ArchiveImage(
            f"registry.k8s.io/kube-proxy:{kube}",
            {"/usr/local/bin/kube-proxy": tools / "kube-proxy"},
            base_layers=[proxy_base],
        ),
        imagearchives.ArchiveImage(
            f"registry.k8s.io/etcd:{ETCD_TAG}", {"/usr/local/bin/etcd": tools / "etcd"}
        ),
        imagearchives.ArchiveImage(
            f"registry.k8s.io/coredns/coredns:{COREDNS_TAG}",
            {"/coredns": tools / "coredns"},
            entrypoint=["/coredns"],
        ),
        imagearchives.ArchiveImage(
            f"registry.k8s.io/pause:{noderootfs.PAUSE_TAG}",
            {"/pause": tools / "pause"},
            entrypoint=["/pause"],
        ),
    ]


def _save_kind_net(log: Path, work: Path) -> Path:
    built = images.build(["kind-net"], progress=lambda line: _append(log, line))["kind-net"]
    archive = work / "kind-net.tar"
    images.builder().save(built.local_reference, archive, kindnet.IMAGE)
    return archive


def _append(log: Path, line: str) -> None:
    with log.open("a") as sink:
        sink.write(line + "\n")


def reference_for(key: str) -> str:
    return f"{REPOSITORY}:{binaries.KUBE_VERSION}-{key}"


def ensure(node_engine: engine.Engine, progress: Callable[[str], None], log: Path) -> str:
    """The node image's reference in `node_engine`, building and importing it if missing.

    Raises:
        noderootfs.NodeImageError, engine.EngineError, images.ImageBuildError: naming the step and `log`.
    """
    wanted = os.environ.get(IMAGE_ENV)
    if wanted:
        if not node_engine.image_exists(wanted):
            progress(f"pulling {wanted}")
            node_engine.docker("pull", wanted, timeout=1800)
        return wanted
    progress("kind tools: kind, kubeadm, kube-proxy, crictl, etcd, coredns, pause (cached by version)")
    tools = build_tools(log)
    control_plane = binaries.find_bin_dir(
        ("kube-apiserver", "kube-controller-manager", "kube-scheduler", "kubectl", "kubelet")
    )
    kind_files = kind_module_dir(log) / "images" / "base" / "files"
    work_parent = binaries.cache_root() / "kind" / "node-image-build"
    work_parent.mkdir(parents=True, exist_ok=True)
    inputs = Inputs(kind_files, tools, control_plane, repository_root() / "testbed" / "images" / "kind-net")
    reference = reference_for(inputs.key())
    if node_engine.image_exists(reference):
        progress(f"node image {reference} is built already")
        return reference
    progress(
        f"building node image {reference} locally: kindest/node for Kubernetes {binaries.KUBE_VERSION}"
        " on cgroup v1 cannot be pulled here (about 3 min)"
    )
    with tempfile.TemporaryDirectory(dir=work_parent) as folder:
        work = Path(folder)
        progress("  pod network image coral/kind-net (buildah, cached by content)")
        kind_net_archive = _save_kind_net(log, work)
        _build(inputs, reference, kind_net_archive, work, node_engine, progress, log)
    return reference


def _build(
    inputs: Inputs,
    reference: str,
    kind_net_archive: Path,
    work: Path,
    node_engine: engine.Engine,
    progress: Callable[[str], None],
    log: Path,
) -> None:
    root = work / "rootfs"
    proxy_base = work / "proxy-base.tar"
    noderootfs.make(
        root, proxy_base, inputs.kind_files, inputs.tools_bin, inputs.control_plane_bin, progress, log
    )
    progress("  preloading the control-plane, kube-proxy, etcd, coredns, pause and coral-kind-net images")
    archives = []
    for image in preloaded_images(inputs.tools_bin, inputs.control_plane_bin, proxy_base):
        archive = work / "archives" / (image.reference.rsplit("/", 1)[-1].replace(":", "_") + ".tar")
        imagearchives.write(image, archive)
        archives.append(archive)
    noderootfs.preload(root, [*archives, kind_net_archive], work, log)
    progress(f"  loading the root filesystem into Docker as {reference}")
    rootfs_tar = work / "node-rootfs.tar"
    noderootfs.logged(
        ["tar", "-C", str(root), "--numeric-owner", "-cf", str(rootfs_tar), "."], log, "tar of the node"
    )
    shutil.rmtree(root)
    # As kind's base image: systemd as PID 1 behind kind's entrypoint, halted by SIGRTMIN+3.
    node = imagearchives.ArchiveImage(
        reference,
        files={},
        base_layers=[rootfs_tar],
        entrypoint=["/usr/local/bin/entrypoint", "/sbin/init"],
        env=(f"PATH={imagearchives.PATH}", "container=docker"),
        stop_signal="SIGRTMIN+3",
    )
    archive = work / "node-image.tar"
    imagearchives.write(node, archive)
    rootfs_tar.unlink()
    noderootfs.logged(
        ["docker", "load", "--input", str(archive)],
        log,
        "docker load of the node image",
        env=node_engine.env(),
    )
    _remove_superseded(node_engine, reference)


def _remove_superseded(node_engine: engine.Engine, reference: str) -> None:
    """Untags earlier builds of the node image (about 1 GB each); one a container still uses stays."""
    listed = node_engine.docker("images", REPOSITORY, "--format", "{{.Repository}}:{{.Tag}}").stdout.split()
    for older in listed:
        if older != reference:
            node_engine.docker("rmi", older, check=False)
