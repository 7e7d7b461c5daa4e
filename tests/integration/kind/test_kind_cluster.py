"""A kind cluster of two robots, made the way `coral dev-cluster kind up` makes it, and gone after.

One test walks what a user relies on: nodes Ready and labelled as robots, a pod on a robot pulling
an image of the project's registry, its logs through `kubectl logs`, a CoreDNS lookup from inside
it, a robot's link cut (its Node stops being Ready) and restored, and nothing left after the
cluster is deleted (no container, network, registry, the project's dockerd or mount; the host's
ip_forward and iptables as before). Skipped, with the reason, where kind cannot run.
"""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest
from coral_testbed import images
from coral_testbed.cluster.client import Cluster
from coral_testbed.images import registry
from coral_testbed.kind import clusters, engine, faults, provisioning
from coral_testbed.waiting import wait_for

pytestmark = [pytest.mark.slow, pytest.mark.timeout(1800)]

NAME = "coral-test"
ROBOTS = {"kind-robot-1": {"coral.dev/model": "kind"}, "kind-robot-2": {"coral.dev/model": "kind"}}
POD = """\
apiVersion: v1
kind: Pod
metadata: {name: hello-robot, namespace: default}
spec:
  nodeSelector: {coral.dev/robot: kind-robot-2}
  restartPolicy: Never
  containers:
  - name: hello
    image: coral/python:3.11-bookworm
    command: [python, -c]
    args:
    - |
      import socket
      print("hello from", socket.gethostname())
      print("kubernetes.default.svc is", socket.gethostbyname("kubernetes.default.svc.cluster.local"))
"""


def _host_network_state() -> tuple[str, str]:
    forwarding = Path("/proc/sys/net/ipv4/ip_forward").read_text().strip()
    rules = subprocess.run(["iptables-save"], capture_output=True, text=True).stdout
    # iptables-save stamps each dump with the time; only the rules matter.
    return forwarding, "\n".join(line for line in rules.splitlines() if not line.startswith("#"))


def _mounts_under(folder: Path) -> list[str]:
    return [line for line in Path("/proc/mounts").read_text().splitlines() if str(folder) in line]


def _ready(cluster: Cluster, node: str) -> str:
    return cluster.kubectl(
        "get", "node", node, "-o", 'jsonpath={.status.conditions[?(@.type=="Ready")].status}'
    ).stdout


def test_a_kind_cluster_of_two_robots_runs_pods_survives_a_cut_link_and_leaves_nothing() -> None:
    reason = provisioning.unsupported_reason()
    if reason:
        pytest.skip(reason)
    host_before = _host_network_state()
    engine_was_running = engine.project_engine_running()
    ready = provisioning.ensure(print)
    started_engine = ready.engine.owned and not engine_was_running
    running = clusters.create(NAME, ROBOTS, ready.engine, ready.node_image, print)
    try:
        cluster = Cluster(running.kubeconfig, None, is_local=False)
        nodes = cluster.kubectl("get", "nodes", "-L", "coral.dev/robot", "-o", "wide").stdout
        print(nodes)
        labelled = cluster.kubectl(
            "get",
            "nodes",
            "-l",
            "coral.dev/robot",
            "-o",
            "jsonpath={.items[*].metadata.labels.coral\\.dev/robot}",
        ).stdout.split()
        assert sorted(labelled) == sorted(ROBOTS), nodes
        for node in running.node_containers():
            assert _ready(cluster, node) == "True", nodes

        images.build(["python"], registry_address=running.registry_address)
        cluster.kubectl("apply", "-f", "-", input=POD)
        wait_for(
            lambda: (
                cluster.kubectl("get", "pod", "hello-robot", "-o", "jsonpath={.status.phase}").stdout
                == "Succeeded"
            ),
            timeout=180,
            message=lambda: (
                "pod hello-robot to succeed: "
                + cluster.kubectl("describe", "pod", "hello-robot", check=False).stdout[-1500:]
            ),
        )
        logs = cluster.kubectl("logs", "hello-robot").stdout
        assert cluster.kubectl("get", "pod", "hello-robot", "-o", "jsonpath={.spec.nodeName}").stdout == (
            faults.node_of(running, "kind-robot-2")
        )
        assert "hello from hello-robot" in logs, logs
        assert "kubernetes.default.svc is 10.96.0.1" in logs, logs

        faults.cut_link(running, "kind-robot-1")
        cut_node = faults.node_of(running, "kind-robot-1")
        wait_for(
            lambda: _ready(cluster, cut_node) in ("False", "Unknown"),
            timeout=180,
            interval=2,
            message=f"{cut_node} to stop being Ready after its link was cut",
        )
        faults.restore_link(running, "kind-robot-1")
        wait_for(
            lambda: _ready(cluster, cut_node) == "True",
            timeout=180,
            interval=2,
            message=f"{cut_node} to be Ready again after its link was restored",
        )
    finally:
        clusters.delete(NAME, ready.engine, print)
        if started_engine:
            engine.stop()

    assert not registry.recorded_addresses(clusters.state_dir(NAME)), "the cluster's registry still runs"
    if started_engine:
        assert not ready.engine.is_serving(), "the project's dockerd still runs"
        assert not _mounts_under(engine.engine_dir()), "mounts of the project's dockerd are left"
        assert not engine.leftover_cgroups(), "cgroups of the project's dockerd are left"
    else:
        assert not ready.engine.containers(f"{clusters.KIND_CLUSTER_LABEL}={NAME}")
        networks = ready.engine.docker("network", "ls", "--format", "{{.Name}}").stdout.split()
        assert clusters.network_name(NAME) not in networks
    assert _host_network_state() == host_before, "the host's ip_forward or iptables changed"
