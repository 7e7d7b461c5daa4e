"""The operator as an administrator installs it: `helm install` of the chart, from its image pulled
from the registry, on a real node that is not a robot, acting only with the chart's RBAC."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from coral_api import Coral, condition, fleet_mission, is_current_and_true
from coral_testbed.cluster import audit, operatorchart
from coral_testbed.cluster.robots import ROBOT_LABEL
from fixtures.operator import HelmOperator
from kubernetes import client as k8s

pytestmark = [pytest.mark.cluster, pytest.mark.real_robots, pytest.mark.slow]


def test_the_operator_pod_serves_a_system_with_only_the_charts_rbac(
    cluster: Any,
    namespace: str,
    helm_operator: HelmOperator,
    operator_node: str,
    robots: Callable[..., list[str]],
    fleet_label: str,
    wait: Any,
) -> None:
    core = k8s.CoreV1Api(cluster.api_client)
    pod = helm_operator.pod
    repository, tag = operatorchart.operator_image()
    assert pod.spec.node_name == operator_node
    assert pod.spec.containers[0].image == f"{repository}:{tag}"
    # The pod's identity is the chart's ServiceAccount, whose token the kubelet projects.
    assert pod.spec.service_account_name == helm_operator.release.name
    status = pod.status.container_statuses[0]
    assert status.ready and status.image_id, status
    node = core.read_node(operator_node)
    assert ROBOT_LABEL not in node.metadata.labels, "the operator's node must not be a robot"
    assert node.status.node_info.container_runtime_version.startswith("containerd://")

    made = robots(2, {"fleet": fleet_label})
    coral = Coral(cluster.api_client, namespace)
    coral.create_system(fleet_mission("fleet", fleet_label))
    wait(
        lambda: is_current_and_true(coral.system("fleet"), "Ready"),
        lambda: f"the system to become Ready; operator logs:\n{helm_operator.logs()[-3000:]}",
        timeout=150,
    )
    instances = cluster.kubectl(
        "get", "coralinstances", "-n", namespace, "-o", "jsonpath={.items[*].spec.robot}"
    ).stdout.split()
    assert sorted(instances) == sorted(made)

    # Nothing else serves this namespace, so the Ready system is the pod's work; its logs (through
    # the kubelet) show it authenticated with the projected token and was never refused.
    logs = helm_operator.logs()
    assert "Initial authentication has finished" in logs, logs[-3000:]
    assert "403" not in logs and "Forbidden" not in logs, logs[-3000:]
    # The same pod, never restarted: the liveness probe passes against the real kubelet.
    again = core.read_namespaced_pod(pod.metadata.name, helm_operator.release.namespace)
    assert again.status.container_statuses[0].restart_count == 0


def test_a_system_grows_from_one_robot_to_three_under_the_charts_rbac(
    cluster: Any,
    namespace: str,
    helm_operator: HelmOperator,
    robots: Callable[..., list[str]],
    fleet_label: str,
    wait: Any,
) -> None:
    """Issue 47, item 8: the shipped ClusterRole lacked `get` on ServiceAccounts. A robot joining a
    system that exists has its executors' account created again, which answers 409 and is then
    read: refused, the system went Stalled (ApplyRefused) and the new robot never got its instance.
    """
    coral = Coral(cluster.api_client, namespace)

    def ready_on(count: int) -> bool:
        current = [i for i in coral.instances().values() if is_current_and_true(i, "Ready")]
        return is_current_and_true(coral.system("fleet"), "Ready") and len(current) == count

    robots(1, {"fleet": fleet_label})
    coral.create_system(fleet_mission("fleet", fleet_label))
    logs = helm_operator.logs
    wait(lambda: ready_on(1), lambda: f"one Ready robot; logs:\n{logs()[-3000:]}", timeout=150)
    made = robots(2, {"fleet": fleet_label}, start=2)
    wait(lambda: ready_on(3), lambda: f"three Ready robots; logs:\n{logs()[-3000:]}", timeout=180)
    assert set(made) <= {i["spec"]["robot"] for i in coral.instances().values()}
    stalled = condition(coral.system("fleet"), "Stalled")
    assert stalled.get("status") == "False", stalled
    if cluster.state_dir is not None:
        account = f"system:serviceaccount:{namespace}:{helm_operator.release.name}"
        requests = audit.requests_of(Path(cluster.state_dir) / "logs" / "audit.log", account)
        assert requests, "the audit log holds none of the operator pod's requests"
        refused = sorted({(r.permission, r.namespace) for r in requests if r.code == 403})
        assert not refused, f"the API server refused the operator's pod: {refused}"
