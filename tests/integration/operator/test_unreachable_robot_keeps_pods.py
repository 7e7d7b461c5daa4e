"""A robot whose Node goes NotReady is reported unreachable with its last heartbeat and keeps its pods."""

from __future__ import annotations

import pytest
from coral_api import condition, is_current_and_true
from fixtures.tolerations import robot_down_tolerations
from scenarios import Scenario

pytestmark = [pytest.mark.cluster, pytest.mark.slow]


def test_an_unreachable_robot_keeps_its_pods(scenario: Scenario) -> None:
    cluster, namespace, coral, wait = scenario.cluster, scenario.namespace, scenario.coral, scenario.wait
    lost, kept = scenario.robots(2)
    scenario.deploy()
    uids = {n: p.metadata.uid for n, p in coral.pods().items()}

    # A pod with the usual 1 s toleration shows that the control plane really evicts from this robot.
    coral.core.create_namespaced_pod(
        namespace,
        {
            "metadata": {"name": "ordinary"},
            "spec": {
                "nodeName": lost,
                "containers": [{"name": "c", "image": "example/ordinary:1"}],
                "tolerations": robot_down_tolerations(seconds=1),
            },
        },
    )
    cluster.set_robot_reachable(lost, False)

    instance_name = f"fleet-{lost}"
    reachable = wait(
        lambda: (
            condition(coral.instances().get(instance_name), "RobotReachable").get("status") == "False"
            and coral.instances()[instance_name]
        ),
        "the instance to report the robot unreachable",
    )
    message = condition(reachable, "RobotReachable")["message"]
    assert "last seen 20" in message and "its pods are kept" in message
    assert reachable["status"]["robot"]["reachable"] is False and reachable["status"]["robot"]["lastSeen"]
    wait(lambda: coral.system("fleet")["status"]["robots"]["unreachable"] == 1, "the system to count it")
    assert condition(coral.system("fleet"), "RobotsReachable")["status"] == "False"

    # Evicted means marked for deletion: an unreachable robot's kubelet cannot confirm it.
    wait(
        lambda: (
            "ordinary" not in coral.pods() or coral.pods()["ordinary"].metadata.deletion_timestamp is not None
        ),
        "the ordinary pod to be evicted from the unreachable robot",
        timeout=120,
    )
    pods = coral.pods()
    for name, uid in uids.items():
        assert pods[name].metadata.uid == uid and pods[name].metadata.deletion_timestamp is None, name
    assert is_current_and_true(coral.instances()[f"fleet-{kept}"], "Ready")

    cluster.set_robot_reachable(lost, True)
    wait(
        lambda: condition(coral.instances().get(instance_name), "RobotReachable").get("status") == "True",
        "the robot to be reachable again",
    )
