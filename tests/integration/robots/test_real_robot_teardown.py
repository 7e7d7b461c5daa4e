"""Removing a real robot leaves nothing behind: no process, mount, network namespace, link or cgroup."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import pytest
from coral_testbed.cluster import Cluster, cgroups, mountview, realrobots
from kubernetes import client as k8s
from kubernetes.client.exceptions import ApiException

from .pods import apply_robot_pod, wait_pod

pytestmark = [pytest.mark.cluster, pytest.mark.real_robots]

ROBOT = "real-gone"


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return Path(f"/proc/{pid}/stat").read_text().split(")")[-1].split()[0] != "Z"


def test_removed_robot_leaves_nothing_behind(
    cluster: Cluster, namespace: str, real_robots: realrobots.RealRobots
) -> None:
    real_robots.add([ROBOT])
    core = k8s.CoreV1Api(cluster.api_client)
    apply_robot_pod(cluster, namespace, "doomed", ROBOT, "exec sleep 3600", host_path="/var/lib/coral/doomed")
    apply_robot_pod(cluster, namespace, "doomed-host", ROBOT, "exec sleep 3600", host_network=True)
    wait_pod(core, namespace, "doomed")
    wait_pod(core, namespace, "doomed-host")
    layout = real_robots.layout(ROBOT)
    pids = cgroups.pids(layout.cgroup_root)
    assert len(pids) >= 5, pids  # containerd, kubelet, shims, pause and main containers

    real_robots.remove([ROBOT])

    assert ROBOT not in real_robots.names()
    assert [pid for pid in pids if _alive(pid)] == []
    assert cgroups.existing(layout.cgroup_root) == []
    assert mountview.mounts_under(layout.dir) == [] and not layout.dir.exists()
    assert not layout.ns_file.exists() and not mountview.uts_file(layout.ns_file).exists()
    namespaces = subprocess.run(["ip", "netns", "list"], capture_output=True, text=True, check=True).stdout
    assert layout.link.netns not in namespaces
    links = subprocess.run(["ip", "-o", "link", "show"], capture_output=True, text=True, check=True).stdout
    assert f" {layout.link.host_veth}@" not in links and f" {layout.link.host_veth}:" not in links
    with pytest.raises(ApiException) as gone:
        core.read_node(ROBOT)
    assert gone.value.status == 404
