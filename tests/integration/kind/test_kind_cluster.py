"""The kind cluster of this folder (conftest.py): its robots as a user relies on them.

Nodes Ready and labelled as robots, a pod on a robot pulling an image of the project's registry,
its logs through `kubectl logs`, a CoreDNS lookup from inside it, a robot's link cut (other
robots and the API server cannot reach it, its Node stops being Ready) and restored, a robot
power-cycled and its containerd killed.
"""

from __future__ import annotations

import pytest
import yaml
from coral_testbed.cluster.client import Cluster
from coral_testbed.kind import clusters, faults
from coral_testbed.waiting import wait_for

from .fleet import ROBOTS, KindCluster

pytestmark = [pytest.mark.slow, pytest.mark.timeout(1800)]

HELLO = """\
import socket
print("hello from", socket.gethostname())
print("kubernetes.default.svc is", socket.gethostbyname("kubernetes.default.svc.cluster.local"))
"""
SERVE_PING = """\
import http.server, pathlib
pathlib.Path("/tmp/www").mkdir(exist_ok=True)
pathlib.Path("/tmp/www/ping").write_text("pong")
handler = lambda *a: http.server.SimpleHTTPRequestHandler(*a, directory="/tmp/www")
http.server.ThreadingHTTPServer(("", 8765), handler).serve_forever()
"""
FETCH = "import sys, urllib.request; print(urllib.request.urlopen(sys.argv[1], timeout=3).read().decode())"


def _python_pod(name: str, robot: str, script: str, restart: str, host_network: bool = False) -> str:
    """A pod of the project's python image on `robot` running `script`, as YAML for kubectl."""
    container = {"name": "main", "image": "coral/python:3.11-bookworm", "command": ["python", "-c", script]}
    spec = {
        "nodeSelector": {"coral.dev/robot": robot},
        "restartPolicy": restart,
        "hostNetwork": host_network,
        "terminationGracePeriodSeconds": 1,
        "containers": [container],
    }
    pod = {
        "apiVersion": "v1",
        "kind": "Pod",
        "metadata": {"name": name, "namespace": "default"},
        "spec": spec,
    }
    return yaml.safe_dump(pod)


def _ready(cluster: Cluster, node: str) -> str:
    return cluster.kubectl(
        "get", "node", node, "-o", 'jsonpath={.status.conditions[?(@.type=="Ready")].status}'
    ).stdout


def _coredns_ready(cluster: Cluster) -> bool:
    replicas = cluster.kubectl(
        "get",
        "deployment",
        "coredns",
        "-n",
        "kube-system",
        "-o",
        "jsonpath={.status.replicas} {.status.readyReplicas}",
    ).stdout.split()
    return len(replicas) == 2 and replicas[0] == replicas[1]


def _dns_routed(running: clusters.Running, cluster: Cluster, node: str) -> bool:
    """Whether `node`'s kube-proxy has written a route to every CoreDNS pod: a node booted
    again starts with empty tables, and its pods cannot resolve names before that."""
    dns_pods = ("pods", "-n", "kube-system", "-l", "k8s-app=kube-dns")
    addresses = cluster.kubectl("get", *dns_pods, "-o", "jsonpath={.items[*].status.podIP}").stdout.split()
    rules = running.engine.docker("exec", node, "iptables-save", "-t", "nat", check=False).stdout
    return bool(addresses) and all(f"kube-system/kube-dns:dns -> {ip}:53" in rules for ip in addresses)


def _run_pod(cluster: Cluster, name: str, robot: str) -> str:
    """Runs the hello pod on `robot` to completion; its logs."""
    cluster.kubectl("apply", "-f", "-", input=_python_pod(name, robot, HELLO, "Never"))

    def phase() -> str:
        return cluster.kubectl("get", "pod", name, "-o", "jsonpath={.status.phase}").stdout

    def outcome() -> str:
        state = cluster.kubectl(
            "get", "pod", name, "-o", "jsonpath={.status.containerStatuses[0].state}", check=False
        ).stdout
        logs = cluster.kubectl("logs", name, check=False)
        return f"pod {name} to succeed: phase {phase()}, state {state}, logs:\n{logs.stdout}{logs.stderr}"

    wait_for(lambda: phase() in ("Succeeded", "Failed"), timeout=180, message=outcome)
    assert phase() == "Succeeded", outcome()
    return cluster.kubectl("logs", name).stdout


def test_each_robot_is_a_ready_worker_labelled_with_its_name(
    kind_cluster: KindCluster,
) -> None:
    running, cluster = kind_cluster.running, kind_cluster.cluster
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
    # A control plane, the robots and the operator's node.
    assert len(running.node_containers()) == 1 + len(ROBOTS) + 1
    for node in running.node_containers():
        assert _ready(cluster, node) == "True", nodes


def test_a_pod_on_a_robot_pulls_from_the_projects_registry_and_resolves_services_through_coredns(
    kind_cluster: KindCluster,
) -> None:
    running, cluster = kind_cluster.running, kind_cluster.cluster
    logs = _run_pod(cluster, "hello-robot", "relay-worker")
    assert cluster.kubectl("get", "pod", "hello-robot", "-o", "jsonpath={.spec.nodeName}").stdout == (
        faults.node_of(running, "relay-worker")
    )
    assert "hello from hello-robot" in logs, logs
    assert "kubernetes.default.svc is 10.96.0.1" in logs, logs


def _running(cluster: Cluster, name: str) -> None:
    wait_for(
        lambda: cluster.kubectl("get", "pod", name, "-o", "jsonpath={.status.phase}").stdout == "Running",
        timeout=180,
        message=lambda: (
            f"pod {name} to run: " + cluster.kubectl("describe", "pod", name, check=False).stdout[-1500:]
        ),
    )


def test_a_robot_whose_link_is_cut_is_isolated_not_ready_and_back_once_restored(
    kind_cluster: KindCluster,
) -> None:
    """Other robots cannot reach it, nor can the API server (`kubectl exec` fails); its Node stops
    being Ready; once the link is restored, all three come back."""
    running, cluster = kind_cluster.running, kind_cluster.cluster
    node = faults.node_of(running, "relay-survey")
    address = faults.robot_address(running, "relay-survey")
    for name, robot in (("server", "relay-survey"), ("prober", "relay-worker")):
        pod = _python_pod(name, robot, SERVE_PING, "Always", host_network=True)
        cluster.kubectl("apply", "-f", "-", input=pod)
    _running(cluster, "server")
    _running(cluster, "prober")

    def fetch() -> str:
        result = cluster.kubectl(
            "exec", "prober", "--", "python", "-c", FETCH, f"http://{address}:8765/ping", check=False
        )
        return result.stdout.strip()

    def exec_on_server() -> str:
        return cluster.kubectl("exec", "server", "--", "cat", "/tmp/www/ping", check=False, timeout=60).stdout

    assert wait_for(fetch, timeout=60, message=f"the prober on relay-worker to reach {node}") == "pong"

    faults.cut_link(running, "relay-survey")
    try:
        assert fetch() == ""
        assert exec_on_server() == ""
        wait_for(
            lambda: _ready(cluster, node) in ("False", "Unknown"),
            timeout=180,
            interval=2,
            message=f"{node} to stop being Ready after its link was cut",
        )
    finally:
        faults.restore_link(running, "relay-survey")
    assert wait_for(fetch, timeout=60, message=f"{node} reachable again") == "pong"
    wait_for(
        lambda: _ready(cluster, node) == "True",
        timeout=180,
        interval=2,
        message=f"{node} to be Ready again after its link was restored",
    )
    # The kubelet asks the API server to authorize each exec, so it serves exec again once it has
    # reconnected on its own.
    wait_for(lambda: exec_on_server() == "pong", timeout=60, message=f"kubectl exec on {node} to work again")
    cluster.kubectl("delete", "pod", "server", "prober", "--wait=false")


def test_a_power_cycled_robot_with_a_killed_containerd_runs_pods_again(
    kind_cluster: KindCluster,
) -> None:
    running, cluster = kind_cluster.running, kind_cluster.cluster
    node = faults.node_of(running, "relay-survey")
    booted = running.engine.docker("inspect", "--format", "{{.State.StartedAt}}", node).stdout
    faults.power_cycle(running, "relay-survey")
    assert running.engine.docker("inspect", "--format", "{{.State.StartedAt}}", node).stdout != booted

    def containerd_active() -> bool:
        state = running.engine.docker("exec", node, "systemctl", "is-active", "containerd", check=False)
        return state.stdout.strip() == "active"

    wait_for(
        containerd_active, timeout=120, interval=1, message=f"containerd of {node} running after the boot"
    )
    faults.kill_containerd(running, "relay-survey")
    wait_for(
        lambda: _ready(cluster, node) == "True" and containerd_active(),
        timeout=180,
        interval=2,
        message=f"{node} Ready with containerd running again",
    )
    # kind schedules CoreDNS on any worker, this robot's too: names resolve again once its pods
    # are Ready, after the robot's boot.
    wait_for(
        lambda: _coredns_ready(cluster),
        timeout=180,
        interval=2,
        message=lambda: (
            "CoreDNS Ready: " + cluster.kubectl("get", "pods", "-n", "kube-system", "-o", "wide").stdout
        ),
    )
    wait_for(
        lambda: _dns_routed(running, cluster, node),
        timeout=120,
        interval=2,
        message=f"kube-proxy of {node} routing to CoreDNS after the boot",
    )
    logs = _run_pod(cluster, "after-power-cycle", "relay-survey")
    assert "kubernetes.default.svc is 10.96.0.1" in logs, logs
