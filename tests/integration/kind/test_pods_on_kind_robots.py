"""Pods on kind robots run as containers: probes, logs, exec, Events, host network and host paths.

Each test applies pods with kubectl, as a user would, and checks what the robot's kubelet and
containerd really did: the pod's address, the files on the robot (read inside its node), what
`kubectl logs` and `exec` return.
"""

from __future__ import annotations

import ipaddress
import json
from typing import Any

import pytest
from coral_testbed.kind import faults
from coral_testbed.waiting import wait_for
from kubernetes import client as k8s

from .fleet import KindCluster, container_address, crictl, on_robot
from .pods import apply_robot_pod, condition, events_for, robot_pod, wait_pod

pytestmark = [pytest.mark.slow, pytest.mark.timeout(1800)]

ROBOTS = ("relay-worker", "relay-survey")


def test_exec_readiness_probe_gates_a_pod_on_the_robots_pod_network(
    kind_cluster: KindCluster, kind_namespace: str, robot_test_image: str
) -> None:
    robot = ROBOTS[0]
    cluster, namespace = kind_cluster.cluster, kind_namespace
    core = k8s.CoreV1Api(cluster.api_client)
    manifest = robot_pod(
        "gated", robot, "echo started on $(hostname); exec sleep 3600", readiness=["test", "-f", "/tmp/ready"]
    )
    cluster.kubectl("apply", "-n", namespace, "-f", "-", input=manifest)

    pod = wait_pod(core, namespace, "gated", ready=False)
    # The pod's address is on the robot's own pod network.
    node = core.read_node(faults.node_of(kind_cluster.running, robot))
    assert ipaddress.ip_address(pod.status.pod_ip) in ipaddress.ip_network(node.spec.pod_cidr)
    # The kubelet reports the failing probe as an Event, as on any cluster.
    wait_for(
        lambda: any(
            e.reason == "Unhealthy" and "Readiness probe failed" in e.message
            for e in events_for(core, namespace, "gated")
        ),
        timeout=60,
        message="a kubelet Event for the failing readiness probe",
    )

    cluster.kubectl("exec", "-n", namespace, "gated", "--", "touch", "/tmp/ready")
    pod = wait_pod(core, namespace, "gated", ready=True)
    assert condition(pod, "ContainersReady") == "True"
    logs = cluster.kubectl("logs", "-n", namespace, "gated").stdout
    assert logs.strip() == "started on gated"


def test_host_network_pod_shares_a_host_path_with_a_bridged_pod(
    kind_cluster: KindCluster, kind_namespace: str, robot_test_image: str
) -> None:
    running, cluster, namespace = kind_cluster.running, kind_cluster.cluster, kind_namespace
    robot, other = ROBOTS
    core = k8s.CoreV1Api(cluster.api_client)
    address = container_address(running, robot)
    folder = f"/var/lib/coral/tests/{namespace}"
    writer = robot_pod(
        "writer",
        robot,
        "ip -o -4 addr show eth0 > /shared/address; exec sleep 3600",
        host_network=True,
        host_path=folder,
    )
    reader = robot_pod(
        "reader",
        robot,
        "while [ ! -s /shared/address ]; do sleep 0.2; done; cat /shared/address; exec sleep 3600",
        host_path=folder,
    )
    cluster.kubectl("apply", "-n", namespace, "-f", "-", input=writer)
    cluster.kubectl("apply", "-n", namespace, "-f", "-", input=reader)

    pod = wait_pod(core, namespace, "writer")
    assert pod.status.pod_ip == address
    wait_pod(core, namespace, "reader")
    wait_for(
        lambda: address in cluster.kubectl("logs", "-n", namespace, "reader").stdout,
        timeout=30,
        message="the bridged pod to print the robot address the host-network pod wrote",
    )
    # The host path lives on the robot itself: the other robot has no such file.
    assert address in on_robot(running, robot, "cat", f"{folder}/address")
    missing = running.engine.docker(
        "exec", faults.node_of(running, other), "test", "-e", f"{folder}/address", check=False
    )
    assert missing.returncode == 1

    exec_result = cluster.kubectl("exec", "-n", namespace, "reader", "--", "cat", "/shared/address")
    assert address in exec_result.stdout


def test_containers_are_visible_through_the_cri(
    kind_cluster: KindCluster, kind_namespace: str, robot_test_image: str
) -> None:
    running, cluster, namespace = kind_cluster.running, kind_cluster.cluster, kind_namespace
    robot = ROBOTS[1]
    core = k8s.CoreV1Api(cluster.api_client)
    apply_robot_pod(cluster, namespace, "seen", robot, "exec sleep 3600")
    pod = wait_pod(core, namespace, "seen")
    container_id = pod.status.container_statuses[0].container_id
    assert container_id.startswith("containerd://")
    listed = crictl(running, robot, "ps", "-q", "--label", f"io.kubernetes.pod.namespace={namespace}")
    assert container_id.removeprefix("containerd://") in listed.split()
    # Killing the container through the CRI makes the kubelet restart it, as it would on a robot.
    crictl(running, robot, "stop", "--timeout", "0", container_id.removeprefix("containerd://"))
    wait_for(
        lambda: core.read_namespaced_pod("seen", namespace).status.container_statuses[0].restart_count >= 1,
        timeout=60,
        message="the kubelet to restart the container stopped through the CRI",
    )
    wait_pod(core, namespace, "seen")


@pytest.mark.parametrize("host_network", [False, True], ids=["bridge", "host-network"])
def test_pods_reach_the_api_at_the_kubernetes_service_with_their_own_token(
    kind_cluster: KindCluster, kind_namespace: str, robot_test_image: str, host_network: bool
) -> None:
    """In-cluster clients use $KUBERNETES_SERVICE_HOST and the pod's projected ServiceAccount token."""
    cluster, namespace = kind_cluster.cluster, kind_namespace
    robot = ROBOTS[0]
    core = k8s.CoreV1Api(cluster.api_client)
    review = '{"apiVersion":"authentication.k8s.io/v1","kind":"SelfSubjectReview"}'
    script = (
        "token=$(cat /var/run/secrets/kubernetes.io/serviceaccount/token); "
        'wget -q -O - --no-check-certificate --header "Authorization: Bearer $token" '
        "--header 'Content-Type: application/json' "
        f"--post-data '{review}' "
        "https://$KUBERNETES_SERVICE_HOST:$KUBERNETES_SERVICE_PORT"
        "/apis/authentication.k8s.io/v1/selfsubjectreviews; echo; "
        "exec sleep 3600"
    )
    apply_robot_pod(cluster, namespace, "whoami", robot, script, host_network=host_network)
    wait_pod(core, namespace, "whoami")
    expected = f"system:serviceaccount:{namespace}:default"

    def review() -> dict[str, Any] | None:
        try:
            return json.loads(cluster.kubectl("logs", "-n", namespace, "whoami").stdout)
        except ValueError:
            return None  # not written completely yet

    answer = wait_for(review, timeout=30, message="the pod to print its SelfSubjectReview")
    assert answer["status"]["userInfo"]["username"] == expected, answer


def test_an_image_that_cannot_be_pulled_is_reported_on_the_pod(
    kind_cluster: KindCluster, kind_namespace: str, robot_test_image: str
) -> None:
    cluster, namespace = kind_cluster.cluster, kind_namespace
    robot = ROBOTS[1]
    core = k8s.CoreV1Api(cluster.api_client)
    image = f"coral.local/no-such-image-{namespace}:1"
    manifest = robot_pod("unpullable", robot, "exec sleep 3600").replace(robot_test_image, image)
    cluster.kubectl("apply", "-n", namespace, "-f", "-", input=manifest)

    def waiting_reason() -> Any:
        statuses = core.read_namespaced_pod("unpullable", namespace).status.container_statuses or []
        waiting = statuses[0].state.waiting if statuses else None
        return waiting if waiting and waiting.reason in ("ErrImagePull", "ImagePullBackOff") else None

    waiting = wait_for(
        waiting_reason, timeout=90, message="the pod to report that its image cannot be pulled"
    )
    assert image in waiting.message
    wait_for(
        lambda: any(
            e.reason == "Failed" and image in e.message for e in events_for(core, namespace, "unpullable")
        ),
        timeout=60,
        message="a kubelet Event naming the image that failed to pull",
    )


def test_host_network_pods_of_two_robots_are_isolated_and_reach_each_other(
    kind_cluster: KindCluster, kind_namespace: str, robot_test_image: str
) -> None:
    """Each robot has its own host network: the same port twice, each robot's own address."""
    running, cluster, namespace = kind_cluster.running, kind_cluster.cluster, kind_namespace
    core = k8s.CoreV1Api(cluster.api_client)
    serve = "mkdir -p /www && hostname > /www/name && exec httpd -f -p 8766 -h /www"
    for robot in ROBOTS:
        apply_robot_pod(cluster, namespace, f"web-{robot}", robot, serve, host_network=True)
    for robot in ROBOTS:
        assert wait_pod(core, namespace, f"web-{robot}").status.pod_ip == container_address(running, robot)
    first, second = ROBOTS
    for source, target in ((first, second), (second, first)):
        url = f"http://{container_address(running, target)}:8766/name"
        answer = cluster.kubectl(
            "exec", "-n", namespace, f"web-{source}", "--", "timeout", "5", "wget", "-qO-", url
        )
        # A host-network pod's hostname is its robot's: its node's name.
        assert answer.stdout.strip() == faults.node_of(running, target)
