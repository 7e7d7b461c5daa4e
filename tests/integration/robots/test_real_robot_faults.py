"""Faults of real robots: a stopped kubelet and a cut network link, and the way back from each.

A stopped kubelet stops reporting: the Node turns NotReady (Ready=Unknown) after the controller
manager's grace period, its tolerating pods stay bound and keep running, and a restarted kubelet
picks them up again. A cut link isolates the robot: other robots cannot reach it, and neither can
the API server (`kubectl exec` fails) until the link is restored.
"""

from __future__ import annotations

import pytest
from coral_testbed.cluster import Cluster, realrobots, robots
from coral_testbed.waiting import holds_for, wait_for
from fixtures.robots import REAL_ROBOTS
from kubernetes import client as k8s

from .pods import robot_pod, wait_pod

pytestmark = [pytest.mark.cluster, pytest.mark.real_robots, pytest.mark.slow]


def _ready(core: k8s.CoreV1Api, name: str) -> str | None:
    return robots.ready_status(core.read_node(name))


def test_stopped_kubelet_turns_the_robot_not_ready_and_keeps_its_pods(
    cluster: Cluster, namespace: str, real_robots: realrobots.RealRobots, real_robot: str
) -> None:
    core = k8s.CoreV1Api(cluster.api_client)
    cluster.kubectl(
        "apply", "-n", namespace, "-f", "-", input=robot_pod("steady", real_robot, "exec sleep 3600")
    )
    before = wait_pod(core, namespace, "steady")
    container = before.status.container_statuses[0].container_id.removeprefix("containerd://")

    real_robots.stop(real_robot)
    wait_for(
        lambda: _ready(core, real_robot) == "Unknown", timeout=120, message=f"{real_robot} to turn NotReady"
    )
    status = cluster.kubectl("get", "node", real_robot, "--no-headers").stdout.split()[1]
    assert status == "NotReady"
    pod = core.read_namespaced_pod("steady", namespace)
    assert pod.spec.node_name == real_robot and pod.metadata.deletion_timestamp is None
    # The container never stopped: the runtime still runs it while its kubelet is down.
    assert container in real_robots.cri(real_robot, "ps", "-q").stdout.split()

    real_robots.start(real_robot)
    assert _ready(core, real_robot) == "True"
    after = wait_pod(core, namespace, "steady")
    assert after.metadata.uid == before.metadata.uid
    assert after.status.container_statuses[0].restart_count == 0


def test_cut_link_isolates_the_robot_until_it_is_restored(
    cluster: Cluster, namespace: str, real_robots: realrobots.RealRobots, real_robot: str
) -> None:
    core = k8s.CoreV1Api(cluster.api_client)
    watcher = next(name for name in REAL_ROBOTS if name != real_robot)
    address = real_robots.address(real_robot)
    server = robot_pod(
        "server",
        real_robot,
        "mkdir -p /www && echo pong > /www/ping && exec httpd -f -p 8765 -h /www",
        host_network=True,
    )
    probe = robot_pod("prober", watcher, "exec sleep 3600", host_network=True)
    cluster.kubectl("apply", "-n", namespace, "-f", "-", input=server)
    cluster.kubectl("apply", "-n", namespace, "-f", "-", input=probe)
    wait_pod(core, namespace, "server")
    wait_pod(core, namespace, "prober")

    def fetch() -> str:
        result = cluster.kubectl(
            "exec",
            "-n",
            namespace,
            "prober",
            "--",
            "timeout",
            "3",
            "wget",
            "-q",
            "-O",
            "-",
            f"http://{address}:8765/ping",
            check=False,
        )
        return result.stdout.strip()

    assert wait_for(fetch, timeout=30, message=f"the prober on {watcher} to reach {real_robot}") == "pong"

    real_robots.cut_link(real_robot)
    assert fetch() == ""
    cut_exec = cluster.kubectl(
        "exec", "-n", namespace, "server", "--", "cat", "/www/ping", check=False, timeout=60
    )
    assert cut_exec.returncode != 0 and "pong" not in cut_exec.stdout
    holds_for(lambda: fetch() == "", duration=5, interval=1, message=f"{real_robot} to stay unreachable")

    real_robots.restore_link(real_robot)
    assert wait_for(fetch, timeout=30, message=f"{real_robot} to be reachable again") == "pong"
    # The kubelet asks the API server to authorize each exec, so it serves exec again once it has
    # reconnected on its own.
    wait_for(
        lambda: (
            cluster.kubectl("exec", "-n", namespace, "server", "--", "cat", "/www/ping", check=False).stdout
            == "pong\n"
        ),
        timeout=60,
        message=f"kubectl exec on {real_robot} to work again",
    )
