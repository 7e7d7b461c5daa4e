"""kind robots are real Nodes: the pinned kubelet with containerd, registered with the robot labels.

What `kubectl get nodes -o wide` shows a user, what the kubelet reports on the Node, and what a
kubelet's own credentials (read on the robot, inside its node) may do.
"""

from __future__ import annotations

import json
import subprocess

import pytest
from coral_testbed.cluster import binaries
from coral_testbed.cluster.client import parse_table
from coral_testbed.kind import faults
from kubernetes import client as k8s

from .fleet import ROBOTS, KindCluster, container_address

pytestmark = [pytest.mark.slow, pytest.mark.timeout(1800)]

KUBELET_KUBECONFIG = "/etc/kubernetes/kubelet.conf"
"""Where kubeadm leaves the kubelet's credentials on every kind node."""


def test_kind_robots_show_the_pinned_kubelet_and_containerd(kind_cluster: KindCluster) -> None:
    running, cluster = kind_cluster.running, kind_cluster.cluster
    wide = cluster.kubectl("get", "nodes", "-o", "wide").stdout
    rows = parse_table(wide)
    for robot in ROBOTS:
        row = rows[faults.node_of(running, robot)]
        assert row["STATUS"] == "Ready", wide
        assert row["VERSION"] == binaries.KUBE_VERSION, wide
        assert row["INTERNAL-IP"] == container_address(running, robot), wide
        assert row["CONTAINER-RUNTIME"].startswith("containerd://"), wide
        assert row["OS-IMAGE"] != "<unknown>", wide


def test_kind_robots_carry_the_robot_label_contract_and_their_own_address(
    kind_cluster: KindCluster,
) -> None:
    running = kind_cluster.running
    core = k8s.CoreV1Api(kind_cluster.cluster.api_client)
    addresses = set()
    for robot in ROBOTS:
        name = faults.node_of(running, robot)
        node = core.read_node(name)
        assert node.metadata.labels["coral.dev/robot"] == robot
        assert node.metadata.labels["kubernetes.io/hostname"] == name
        internal = [a.address for a in node.status.addresses if a.type == "InternalIP"]
        assert internal == [container_address(running, robot)]
        addresses.add(internal[0])
        assert node.status.node_info.kubelet_version == binaries.KUBE_VERSION
    assert len(addresses) == len(ROBOTS)


def test_each_kubelet_may_touch_only_its_own_node(kind_cluster: KindCluster) -> None:
    """The kubelets authenticate as system:node:<name>, so the Node authorizer confines each to its
    Node: someone on a robot holding its kubelet's credentials can touch no other robot."""
    running, cluster = kind_cluster.running, kind_cluster.cluster
    robot, other_robot = sorted(ROBOTS)[:2]
    own, other = faults.node_of(running, robot), faults.node_of(running, other_robot)
    patch = json.dumps({"metadata": {"labels": {"coral.dev/stolen": "yes"}}})

    def as_kubelet(*args: str) -> subprocess.CompletedProcess[str]:
        kubectl = ("kubectl", "--kubeconfig", KUBELET_KUBECONFIG)
        return running.engine.docker("exec", own, *kubectl, *args, check=False)

    whoami = as_kubelet("auth", "whoami")
    assert f"system:node:{own}" in whoami.stdout, whoami.stdout + whoami.stderr
    allowed, refused = (
        as_kubelet("patch", "node", own, "-p", patch),
        as_kubelet("patch", "node", other, "-p", patch),
    )
    assert refused.returncode != 0 and "forbidden" in refused.stderr.lower(), refused.stderr
    # NodeRestriction admission also refuses a kubelet that relabels itself under protected keys,
    # but labels of its own prefix are its to set.
    assert allowed.returncode == 0, allowed.stderr
    cluster.kubectl("label", "node", own, "coral.dev/stolen-")
    assert "coral.dev/stolen" not in (k8s.CoreV1Api(cluster.api_client).read_node(other).metadata.labels)
