"""A robot's cgroup subtree in every cgroup hierarchy of the host (cgroup v1, and v2 if mounted).

Used by `realrobots`. The kubelet's `cgroupRoot` must exist in every v1 hierarchy before it
starts; the node's own processes (containerd, its shims) go into `<root>/runtime`, so that
teardown finds every process of the robot in one subtree, kills them, and removes the folders
deepest first.
"""

from __future__ import annotations

import os
import signal
from pathlib import Path

import psutil

from coral_testbed.waiting import wait_for


def hierarchies() -> list[Path]:
    """Mount points of every cgroup hierarchy (each v1 controller, named ones, and v2)."""
    mounted = psutil.disk_partitions(all=True)
    return [Path(mount.mountpoint) for mount in mounted if mount.fstype in ("cgroup", "cgroup2")]


def _relative(path: str) -> str:
    return path.strip("/")


def create(path: str) -> None:
    for hierarchy in hierarchies():
        folder = hierarchy
        for part in Path(_relative(path)).parts:
            parent, folder = folder, folder / part
            folder.mkdir(exist_ok=True)
            # A new v1 cpuset cgroup has no CPUs or memory nodes, and refuses tasks until given some.
            for setting in ("cpuset.cpus", "cpuset.mems"):
                if (folder / setting).exists() and not (folder / setting).read_text().strip():
                    (folder / setting).write_text((parent / setting).read_text())


def join(path: str, pid: int) -> None:
    """Moves `pid` into `path` in every hierarchy (call from the child before it execs)."""
    for hierarchy in hierarchies():
        folder = hierarchy / _relative(path)
        procs = folder / "cgroup.procs"
        if procs.exists():
            procs.write_text(str(pid))


def pids(path: str) -> set[int]:
    found: set[int] = set()
    for hierarchy in hierarchies():
        top = hierarchy / _relative(path)
        if not top.exists():
            continue
        for folder, _, _ in os.walk(top):
            try:
                found.update(int(p) for p in (Path(folder) / "cgroup.procs").read_text().split())
            except OSError:
                continue
    return found


def kill_all(path: str, timeout: float = 15.0) -> None:
    """SIGKILLs every process in the subtree until none is left.

    Raises:
        WaitTimeout: processes were still there after `timeout` seconds.
    """

    def none_left() -> bool:
        # A process forking while it is killed leaves a child behind: each pass kills what is left.
        left = pids(path)
        for pid in left:
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        return not left

    wait_for(
        none_left,
        timeout=timeout,
        interval=0.1,
        message=lambda: f"processes {sorted(pids(path))} in cgroup {path} to die of SIGKILL",
    )


def remove(path: str) -> None:
    """Removes the subtree in every hierarchy, deepest folders first (they must hold no process)."""
    for hierarchy in hierarchies():
        top = hierarchy / _relative(path)
        if not top.exists():
            continue
        for folder, _, _ in sorted(os.walk(top), key=lambda entry: -entry[0].count("/")):
            try:
                os.rmdir(folder)
            except FileNotFoundError:
                pass
            except OSError:
                # Still busy: `existing` reports it, and teardown goes on with the rest.
                continue


def existing(path: str) -> list[Path]:
    """The hierarchies' folders of `path` that exist now (empty after a clean teardown)."""
    return [h / _relative(path) for h in hierarchies() if (h / _relative(path)).exists()]
