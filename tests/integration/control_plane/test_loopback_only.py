"""Every server the local control plane starts listens on 127.0.0.1 only (read from /proc, not flags)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from coral_testbed.cluster import Cluster, controlplane

pytestmark = pytest.mark.cluster

_LISTEN = "0A"


def _socket_inodes(pid: int) -> set[str]:
    inodes = set()
    for fd in Path(f"/proc/{pid}/fd").iterdir():
        try:
            target = os.readlink(fd)
        except OSError:
            continue
        if target.startswith("socket:["):
            inodes.add(target[len("socket:[") : -1])
    return inodes


def _listening(inodes: set[str]) -> list[tuple[str, str]]:
    """(table, local address in /proc hex form) of listening TCP sockets among `inodes`."""
    found = []
    for table in ("tcp", "tcp6"):
        for line in Path(f"/proc/net/{table}").read_text().splitlines()[1:]:
            fields = line.split()
            if fields[3] == _LISTEN and fields[9] in inodes:
                found.append((table, fields[1]))
    return found


def test_every_component_listens_on_loopback_only(cluster: Cluster) -> None:
    if not cluster.is_local:
        pytest.skip("only the local control plane's processes can be inspected")
    state = controlplane.load_state(cluster.kubeconfig.parent)
    assert state is not None
    for process in state.processes:
        sockets = _listening(_socket_inodes(process.pid))
        assert sockets, f"{process.name} listens on nothing"
        for table, address in sockets:
            host = address.split(":")[0]
            assert table == "tcp" and host == "0100007F", f"{process.name} listens on {table} {address}"
