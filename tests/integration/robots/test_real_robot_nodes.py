"""Real robots are real Nodes: the upstream kubelet with containerd, registered with the robot labels.

What `kubectl get nodes -o wide` shows a user, and what the kubelet reports on the Node.
"""

from __future__ import annotations

import json

import pytest
from coral_testbed.cluster import Cluster, binaries, realrobots
from coral_testbed.cluster.client import parse_table
from fixtures.robots import REAL_ROBOTS
from kubernetes import client as k8s

pytestmark = [pytest.mark.cluster, pytest.mark.real_robots]


def test_real_robots_show_the_pinned_kubelet_and_containerd(
    cluster: Cluster, real_robots: realrobots.RealRobots
) -> None:
    wide = cluster.kubectl("get", "nodes", "-o", "wide").stdout
    rows = parse_table(wide)
    for name in REAL_ROBOTS:
        assert rows[name]["STATUS"] == "Ready", wide
        assert rows[name]["VERSION"] == binaries.KUBE_VERSION, wide
        assert rows[name]["INTERNAL-IP"] == real_robots.address(name), wide
        assert rows[name]["CONTAINER-RUNTIME"].startswith("containerd://"), wide
        assert rows[name]["OS-IMAGE"] != "<unknown>", wide


def test_real_robots_carry_the_robot_label_contract_and_their_own_address(
    cluster: Cluster, real_robots: realrobots.RealRobots
) -> None:
    core = k8s.CoreV1Api(cluster.api_client)
    addresses = set()
    for name in REAL_ROBOTS:
        node = core.read_node(name)
        assert node.metadata.labels["coral.dev/robot"] == name
        assert node.metadata.labels["kubernetes.io/hostname"] == name
        internal = [a.address for a in node.status.addresses if a.type == "InternalIP"]
        assert internal == [real_robots.address(name)]
        addresses.add(internal[0])
        assert node.status.node_info.kubelet_version == binaries.KUBE_VERSION
    assert len(addresses) == len(REAL_ROBOTS)


def test_each_kubelet_may_touch_only_its_own_node(
    cluster: Cluster, real_robots: realrobots.RealRobots
) -> None:
    """The kubelets authenticate as system:node:<name>, so the Node authorizer confines each to its Node."""
    own, other = REAL_ROBOTS
    config = real_robots.layout(own).kubelet_kubeconfig
    patch = json.dumps({"metadata": {"labels": {"coral.dev/stolen": "yes"}}})
    allowed = cluster.kubectl("--kubeconfig", str(config), "patch", "node", own, "-p", patch, check=False)
    refused = cluster.kubectl("--kubeconfig", str(config), "patch", "node", other, "-p", patch, check=False)
    assert refused.returncode != 0 and "forbidden" in refused.stderr.lower(), refused.stderr
    # NodeRestriction admission also refuses a kubelet that relabels itself under protected keys,
    # but labels of its own prefix are its to set.
    assert allowed.returncode == 0, allowed.stderr
    cluster.kubectl("label", "node", own, "coral.dev/stolen-")
