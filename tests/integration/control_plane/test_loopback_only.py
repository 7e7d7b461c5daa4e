"""Every server the local control plane starts listens on 127.0.0.1 only: read from the kernel's
socket tables (through psutil), not from the flags it was given."""

from __future__ import annotations

import socket

import psutil
import pytest
from coral_testbed.cluster import Cluster, controlplane

pytestmark = pytest.mark.cluster


def _listening(pid: int) -> list[tuple[socket.AddressFamily, str]]:
    """(address family, local host) of the TCP sockets `pid` listens on, as the kernel reports them."""
    return [
        (connection.family, connection.laddr.ip)
        for connection in psutil.Process(pid).net_connections(kind="tcp")
        if connection.status == psutil.CONN_LISTEN
    ]


def test_every_component_listens_on_loopback_only(cluster: Cluster) -> None:
    if not cluster.is_local:
        pytest.skip("only the local control plane's processes can be inspected")
    state = controlplane.load_state(cluster.kubeconfig.parent)
    assert state is not None
    for process in state.processes:
        sockets = _listening(process.pid)
        assert sockets, f"{process.name} listens on nothing"
        for family, host in sockets:
            assert family == socket.AF_INET and host == "127.0.0.1", f"{process.name} listens on {host}"
