"""A robot's own view of host paths and its own host name: persistent mount and UTS namespaces.

Used by `realrobots`. The namespace is kept alive by a bind mount of its nsfs file in a folder that
is itself a private mount (a namespace file may not sit on a shared mount), so the kubelet and
containerd can join it with `nsenter --mount=FILE` at any time. Inside it, each path in `PRIVATE`
is a bind mount of a folder in the robot's state folder; every mount the kubelet and containerd
make later (volumes, rootfs, pod network namespaces) stays inside the namespace and vanishes
with it. The UTS namespace beside it carries the robot's name as host name, which host-network
pods see, as on a real robot.
"""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import psutil

# Paths a node owns: the plugin root, pod logs, and the kubelet's and containerd's state.
PRIVATE = (
    "/var/lib/coral",
    "/var/log/pods",
    "/var/log/containers",
    "/var/lib/kubelet",
    "/var/lib/containerd",
    "/run/containerd",
)


class MountError(RuntimeError):
    """A mount command failed; the message has the command and its output."""


def _run(*argv: str) -> None:
    result = subprocess.run(list(argv), capture_output=True, text=True, timeout=30, check=False)
    if result.returncode != 0:
        raise MountError(f"`{' '.join(argv)}` exited with {result.returncode}: {result.stderr.strip()}")


def _mount_points() -> list[str]:
    # Not os.path.ismount: a folder bind-mounted onto itself stays on the same device, which it
    # cannot tell from a plain folder; the mount table (read by psutil) lists it.
    return [mount.mountpoint for mount in psutil.disk_partitions(all=True)]


def is_mountpoint(path: Path) -> bool:
    return str(path.resolve()) in _mount_points()


def ensure_private_folder(folder: Path) -> None:
    """Makes `folder` a private bind mount of itself, where namespace files may be kept."""
    folder.mkdir(parents=True, exist_ok=True)
    if not is_mountpoint(folder):
        _run("mount", "--bind", str(folder), str(folder))
    _run("mount", "--make-private", str(folder))


def release_private_folder(folder: Path) -> None:
    if folder.exists() and is_mountpoint(folder):
        _run("umount", "--lazy", str(folder))


def host_path(root: Path, path: str) -> Path:
    """Where the robot's `path` is on the host: inside `root` for private paths, else the path itself."""
    normal = os.path.normpath("/" + path.lstrip("/"))
    for private in PRIVATE:
        if normal == private or normal.startswith(private + "/"):
            return root / normal.lstrip("/")
    return Path(normal)


def uts_file(ns_file: Path) -> Path:
    """Where the UTS namespace that goes with the mount namespace at `ns_file` is pinned."""
    return ns_file.with_suffix(".uts")


def create(ns_file: Path, root: Path, hostname: str) -> None:
    """Creates the namespaces pinned at `ns_file` (mounts: each `PRIVATE` path bound to `root`/path)
    and `uts_file(ns_file)` (host name `hostname`)."""
    binds = []
    for private in PRIVATE:
        source = root / private.lstrip("/")
        source.mkdir(parents=True, exist_ok=True)
        # The mount point must exist on the host; an empty folder is all that is left there.
        Path(private).mkdir(parents=True, exist_ok=True)
        binds.append(f"mount --bind {source} {private}")
    ns_file.touch()
    uts_file(ns_file).touch()
    _run(
        "unshare",
        f"--mount={ns_file}",
        f"--uts={uts_file(ns_file)}",
        "--propagation=private",
        "--",
        "sh",
        "-ec",
        " && ".join([*binds, f"hostname {hostname}"]),
    )


def remove(ns_file: Path) -> None:
    """Releases the namespaces (they disappear once no process is left in them)."""
    for pinned in (ns_file, uts_file(ns_file)):
        if pinned.exists():
            if is_mountpoint(pinned):
                _run("umount", str(pinned))
            pinned.unlink()


def mounts_under(folder: Path) -> list[str]:
    """Mount points on the host at or below `folder` (empty after a clean teardown)."""
    prefix = str(folder.resolve())
    return [p for p in _mount_points() if p == prefix or p.startswith(prefix + "/")]
