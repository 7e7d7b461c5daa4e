"""Applying the fleet example puts one CoralInstance and its pods on each matching robot, in order."""

from __future__ import annotations

import pytest
from coral_api import is_current_and_true, pod_ready_since
from coral_operator.planning import naming
from scenarios import Scenario

pytestmark = [pytest.mark.cluster, pytest.mark.slow]


def test_the_fleet_example_runs_on_every_matching_robot(scenario: Scenario) -> None:
    cluster, namespace, coral = scenario.cluster, scenario.namespace, scenario.coral
    fleet = scenario.robots(3)
    other = scenario.make_robots(1, {"fleet": "someone-else"}, start=9)
    coral.create_system(scenario.mission())

    cluster.kubectl(
        "wait", "--for=condition=Ready", "coralsystem/fleet", "-n", namespace, "--timeout=120s", timeout=130
    )
    system = coral.system("fleet")
    assert system["status"]["robots"] == {"matched": 3, "ready": 3, "updated": 3, "unreachable": 0}

    instances = coral.instances()
    assert sorted(i["spec"]["robot"] for i in instances.values()) == sorted(fleet)
    assert other[0] not in {i["spec"]["robot"] for i in instances.values()}
    for instance in instances.values():
        assert is_current_and_true(instance, "Ready")
        assert instance["metadata"]["ownerReferences"][0]["uid"] == system["metadata"]["uid"]

    pods = coral.pods()
    assert len(pods) == 9
    for name, pod in pods.items():
        robot = pod.metadata.labels["coral.dev/robot"]
        assert pod.spec.node_name == robot, name
        assert pod.metadata.owner_references[0].kind == "CoralInstance"
        assert pod.spec.host_network and pod.spec.host_ipc
        no_execute = {(t.key, t.toleration_seconds) for t in pod.spec.tolerations if t.effect == "NoExecute"}
        assert no_execute == {
            ("node.kubernetes.io/unreachable", None),
            ("node.kubernetes.io/not-ready", None),
        }
        env = {e.name: e.value for e in pod.spec.containers[0].env}
        assert env["ROS_DOMAIN_ID"] == "0" and env["RMW_IMPLEMENTATION"] == "rmw_fastrtps_cpp"
        assert env["CORAL_ROBOT"] == robot
        volumes = {v.name: v for v in pod.spec.volumes}
        assert volumes["plugins"].host_path.path == f"/var/lib/coral/plugins/{namespace}/fleet"

    # Pod names end in a content digest; the labels say which robot and component a pod runs.
    by_component = {
        (pod.metadata.labels["coral.dev/robot"], pod.metadata.labels["coral.dev/component"]): pod
        for pod in pods.values()
    }
    for robot in fleet:
        driver, slam, executor = (by_component[(robot, c)] for c in ("lidar-driver", "slam", "executor"))
        # Ordered startup: each stage is created only after the previous one reported Ready.
        assert slam.metadata.creation_timestamp >= pod_ready_since(driver)
        assert executor.metadata.creation_timestamp >= pod_ready_since(slam)
        assert executor.spec.service_account_name == naming.executor_account_name("fleet")
        config = [
            s.config_map.name for s in {v.name: v for v in executor.spec.volumes}["config"].projected.sources
        ]
        assert any("-tree-" in name for name in config) and any("-params-" in name for name in config)

    events = cluster.kubectl("get", "events", "-n", namespace, "-o", "name").stdout
    assert events.strip(), "the operator posts Events"
