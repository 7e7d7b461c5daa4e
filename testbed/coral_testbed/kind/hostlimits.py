"""The host's inotify limits, raised where they are below what kind nodes need; never lowered.

Every kind node runs its own systemd, journald, kubelet and containerd, and each takes inotify
instances of the host's root user. The kernel's default of 128 instances per user is used up by
two clusters side by side (the suite's and a demo's, say): a node that boots then stops in its
systemd ("Failed to create control group inotify object: Too many open files") and never comes
back. kind's known issues give the values below. Like the Docker engine the setup installs, they
stay until the host reboots; the host's forwarding and firewall are not touched.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

INOTIFY = Path("/proc/sys/fs/inotify")
WANTED = {"max_user_instances": 512, "max_user_watches": 524288}
"""Setting under `INOTIFY` -> the least a host of several kind nodes needs."""


def raises(current: Mapping[str, int]) -> dict[str, int]:
    """Of `WANTED`, the settings `current` holds less of, with their wanted values; one the host
    lacks is not asked for. Pure."""
    return {name: least for name, least in WANTED.items() if name in current and current[name] < least}


def ensure(folder: Path = INOTIFY) -> list[str]:
    """Raises the limits under `folder` that are too low; a line for each change or refusal."""
    current = {name: int((folder / name).read_text()) for name in WANTED if (folder / name).exists()}
    lines: list[str] = []
    for name, value in raises(current).items():
        try:
            (folder / name).write_text(f"{value}\n")
        except OSError as error:
            lines.append(
                f"fs.inotify.{name} stays {current[name]} ({error.strerror}): kind nodes may fail "
                f"to boot with 'Too many open files'; raise it to {value} (sysctl)"
            )
        else:
            was = current[name]
            lines.append(f"fs.inotify.{name} raised from {was} to {value} (kind's nodes need it)")
    return lines
