"""The operator as an administrator installs it: `helm install` of the chart, from its image pulled
from the cluster's registry, on a kind worker that is not a robot, acting only with the chart's RBAC
(`kind_operator`: nothing else serves its namespace)."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from coral_testbed.cluster import operatorchart
from coral_testbed.kind import clusters, faults
from coral_testbed.kind.missions import KindMissionStack
from coral_testbed.waiting import wait_for
from fixtures.conditions import condition, is_current_and_true
from missions import realsystems as rs

from .fleet import ROBOTS, fleet_system

pytestmark = [pytest.mark.slow, pytest.mark.timeout(1800)]

FLEET = "helm-fleet"
"""The label (`fleet=helm-fleet`) the tests' systems select robots by; put on and taken off here."""
TREE = '<root BTCPP_format="4"><BehaviorTree ID="Main"><Sleep msec="600000"/></BehaviorTree></root>'


@pytest.fixture
def fleet_labels(kind_operator: KindMissionStack) -> Iterator[None]:
    """Takes the tests' fleet label off every robot after the test."""
    yield
    for robot in ROBOTS:
        node = faults.node_of(kind_operator.running, robot)
        kind_operator.cluster.kubectl("label", "node", node, "fleet-")


def _label(missions: KindMissionStack, robots: list[str]) -> None:
    """Robots join the tests' fleet by `kubectl label node`, as an administrator adds robots to one."""
    for robot in robots:
        node = faults.node_of(missions.running, robot)
        missions.cluster.kubectl("label", "node", node, f"fleet={FLEET}", "--overwrite")


def _system() -> dict[str, object]:
    return fleet_system("fleet", 0, TREE, robots={"matchLabels": {"fleet": FLEET}})


def _ready_on(missions: KindMissionStack, count: int) -> bool:
    system = missions.custom.get_namespaced_custom_object(
        rs.GROUP, rs.VERSION, missions.namespace, "coralsystems", "fleet"
    )
    current = [i for i in missions.instances() if is_current_and_true(i, "Ready")]
    return is_current_and_true(system, "Ready") and len(current) == count


def _refusals(logs: str) -> list[str]:
    """The operator's log lines about a request the API server refused: the client's exception
    reads `(403)` and `Reason: Forbidden`, the server's message `... is forbidden: ...`, kopf's
    `APIForbiddenError`. A bare "403" would also match a timestamp's milliseconds."""
    return [line for line in logs.splitlines() if "forbidden" in line.lower() or "(403)" in line]


def test_the_operator_pod_serves_a_system_with_only_the_charts_rbac(
    kind_operator: KindMissionStack, fleet_labels: None
) -> None:
    missions = kind_operator
    release = missions.release
    pods = operatorchart.operator_pods(missions.cluster.api_client, release)
    assert len(pods) == 1, [p.metadata.name for p in pods]
    pod = pods[0]
    repository, tag = operatorchart.operator_image()
    operator_node = missions.core.read_node(pod.spec.node_name)
    assert operator_node.metadata.labels.get(operatorchart.OPERATOR_NODE_LABEL) == "true"
    assert pod.spec.containers[0].image == f"{repository}:{tag}"
    # The pod's identity is the chart's ServiceAccount, whose token the kubelet projects.
    assert pod.spec.service_account_name == release.name
    status = pod.status.container_statuses[0]
    assert status.ready and status.image_id, status
    assert clusters.ROBOT_LABEL not in operator_node.metadata.labels, (
        "the operator's node must not be a robot"
    )
    assert operator_node.status.node_info.container_runtime_version.startswith("containerd://")

    made = sorted(ROBOTS)[:2]
    _label(missions, made)
    rs.create(missions.custom, missions.namespace, _system())
    wait_for(
        lambda: _ready_on(missions, len(made)),
        timeout=150,
        message=lambda: f"the system to become Ready; operator logs:\n{missions.operator_log_tail()}",
    )
    assert sorted(i["spec"]["robot"] for i in missions.instances()) == made

    # Nothing else serves this namespace, so the Ready system is the pod's work; its logs (through
    # the kubelet) show it authenticated with the projected token and was never refused.
    logs = missions.operator_log_tail(10**7)
    assert "Initial authentication has finished" in logs, logs[-3000:]
    refused = _refusals(logs)
    assert not refused, refused[:5]
    # The same pod, never restarted: the liveness probe passes against the real kubelet.
    again = missions.core.read_namespaced_pod(pod.metadata.name, release.namespace)
    assert again.status.container_statuses[0].restart_count == 0


def test_a_system_grows_from_one_robot_to_three_under_the_charts_rbac(
    kind_operator: KindMissionStack, fleet_labels: None
) -> None:
    """Issue 47, item 8: the shipped ClusterRole lacked `get` on ServiceAccounts. A robot joining a
    system that exists has its executors' account created again, which answers 409 and is then
    read: refused, the system went Stalled (ApplyRefused) and the new robot never got its instance.
    """
    missions = kind_operator
    first, *others = sorted(ROBOTS)
    _label(missions, [first])
    rs.create(missions.custom, missions.namespace, _system())
    logs = missions.operator_log_tail
    wait_for(lambda: _ready_on(missions, 1), timeout=150, message=lambda: f"one Ready robot; logs:\n{logs()}")
    _label(missions, others)
    wait_for(
        lambda: _ready_on(missions, 3), timeout=180, message=lambda: f"three Ready robots; logs:\n{logs()}"
    )
    assert set(others) <= {i["spec"]["robot"] for i in missions.instances()}
    system = missions.custom.get_namespaced_custom_object(
        rs.GROUP, rs.VERSION, missions.namespace, "coralsystems", "fleet"
    )
    stalled = condition(system, "Stalled")
    assert stalled.get("status") == "False", stalled
    refused = _refusals(missions.operator_log_tail(10**7))
    assert not refused, refused[:5]
