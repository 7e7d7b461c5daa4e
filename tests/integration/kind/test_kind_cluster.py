"""A kind cluster of two robots, made the way `coral dev-cluster kind up` makes it, and gone after.

The module's cluster is created once; the tests check what a user relies on: nodes Ready and
labelled as robots, a pod on a robot pulling an image of the project's registry, its logs through
`kubectl logs`, a CoreDNS lookup from inside it, a robot's link cut (its Node stops being Ready) and
restored, a robot power-cycled and its containerd killed. After the cluster is deleted nothing may
be left (no container, network, registry, the project's dockerd, mount or cgroup; the host's
ip_forward and iptables as before). Skipped, with the reason, where kind cannot run.
"""

from __future__ import annotations

import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest
from coral_testbed import images
from coral_testbed.cluster import binaries
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
metadata: {name: %(name)s, namespace: default}
spec:
  nodeSelector: {coral.dev/robot: %(robot)s}
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


def _assert_nothing_left(node_engine: engine.Engine, engine_started_here: bool) -> None:
    assert not registry.recorded_addresses(clusters.state_dir(NAME)), "the cluster's registry still runs"
    if engine_started_here:
        assert not node_engine.is_serving(), "the project's dockerd still runs"
        assert not _mounts_under(engine.engine_dir()), "mounts of the project's dockerd are left"
        assert not engine.leftover_cgroups(), "cgroups of the project's dockerd are left"
    else:
        assert not node_engine.containers(f"{clusters.KIND_CLUSTER_LABEL}={NAME}")
        networks = node_engine.docker("network", "ls", "--format", "{{.Name}}").stdout.split()
        assert clusters.network_name(NAME) not in networks


@pytest.fixture(scope="module")
def kind_cluster() -> Iterator[tuple[clusters.Running, Cluster]]:
    """The two-robot cluster, with the python image in its registry; everything gone afterwards."""
    reason = provisioning.unsupported_reason()
    if reason:
        pytest.skip(reason)
    host_before = _host_network_state()
    engine_was_running = engine.project_engine_running()
    ready = provisioning.ensure(print)
    started_here = ready.engine.owned and not engine_was_running
    try:
        running = clusters.create(NAME, ROBOTS, ready.engine, ready.node_image, print)
        images.build(["python"], registry_address=running.registry_address)
        yield running, Cluster(running.kubeconfig, binaries.find_bin_dir(("kubectl",)), is_local=False)
    finally:
        clusters.delete(NAME, ready.engine, print)
        if started_here:
            engine.stop()
    _assert_nothing_left(ready.engine, started_here)
    assert _host_network_state() == host_before, "the host's ip_forward or iptables changed"


def _run_pod(cluster: Cluster, name: str, robot: str) -> str:
    """Runs the hello pod on `robot` to completion; its logs."""
    cluster.kubectl("apply", "-f", "-", input=POD % {"name": name, "robot": robot})
    wait_for(
        lambda: cluster.kubectl("get", "pod", name, "-o", "jsonpath={.status.phase}").stdout == "Succeeded",
        timeout=180,
        message=lambda: (
            f"pod {name} to succeed: " + cluster.kubectl("describe", "pod", name, check=False).stdout[-1500:]
        ),
    )
    return cluster.kubectl("logs", name).stdout


def test_each_robot_is_a_ready_worker_labelled_with_its_name(
    kind_cluster: tuple[clusters.Running, Cluster],
) -> None:
    running, cluster = kind_cluster
    nodes = cluster.kubectl("get", "nodes", "-L", "coral.dev/robot", "-o", "wide").stdout
    labelled = cluster.kubectl(
        "get",
        "nodes",
        "-l",
        "coral.dev/robot",
        "-o",
        "jsonpath={.items[*].metadata.labels.coral\\.dev/robot}",
    ).stdout.split()
    assert sorted(labelled) == sorted(ROBOTS), nodes
    assert len(running.node_containers()) == 1 + len(ROBOTS)
    for node in running.node_containers():
        assert _ready(cluster, node) == "True", nodes


def test_a_pod_on_a_robot_pulls_from_the_projects_registry_and_resolves_services_through_coredns(
    kind_cluster: tuple[clusters.Running, Cluster],
) -> None:
    running, cluster = kind_cluster
    logs = _run_pod(cluster, "hello-robot", "kind-robot-2")
    assert cluster.kubectl("get", "pod", "hello-robot", "-o", "jsonpath={.spec.nodeName}").stdout == (
        faults.node_of(running, "kind-robot-2")
    )
    assert "hello from hello-robot" in logs, logs
    assert "kubernetes.default.svc is 10.96.0.1" in logs, logs


def test_a_robot_whose_link_is_cut_stops_being_ready_and_is_ready_again_once_restored(
    kind_cluster: tuple[clusters.Running, Cluster],
) -> None:
    running, cluster = kind_cluster
    node = faults.node_of(running, "kind-robot-1")
    faults.cut_link(running, "kind-robot-1")
    try:
        wait_for(
            lambda: _ready(cluster, node) in ("False", "Unknown"),
            timeout=180,
            interval=2,
            message=f"{node} to stop being Ready after its link was cut",
        )
    finally:
        faults.restore_link(running, "kind-robot-1")
    wait_for(
        lambda: _ready(cluster, node) == "True",
        timeout=180,
        interval=2,
        message=f"{node} to be Ready again after its link was restored",
    )


def test_a_power_cycled_robot_with_a_killed_containerd_runs_pods_again(
    kind_cluster: tuple[clusters.Running, Cluster],
) -> None:
    running, cluster = kind_cluster
    node = faults.node_of(running, "kind-robot-1")
    booted = running.engine.docker("inspect", "--format", "{{.State.StartedAt}}", node).stdout
    faults.power_cycle(running, "kind-robot-1")
    assert running.engine.docker("inspect", "--format", "{{.State.StartedAt}}", node).stdout != booted

    def containerd_active() -> bool:
        state = running.engine.docker("exec", node, "systemctl", "is-active", "containerd", check=False)
        return state.stdout.strip() == "active"

    wait_for(
        containerd_active, timeout=120, interval=1, message=f"containerd of {node} running after the boot"
    )
    faults.kill_containerd(running, "kind-robot-1")
    wait_for(
        lambda: _ready(cluster, node) == "True" and containerd_active(),
        timeout=180,
        interval=2,
        message=f"{node} Ready with containerd running again",
    )
    logs = _run_pod(cluster, "after-power-cycle", "kind-robot-1")
    assert "kubernetes.default.svc is 10.96.0.1" in logs, logs
