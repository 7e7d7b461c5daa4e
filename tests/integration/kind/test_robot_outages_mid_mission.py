"""A kind robot that goes away mid-mission, and comes back: what its CoralInstance says, what the
mission does.

The operator runs from its Helm chart on the cluster's operator node (`kind_operator`); a
CoralSystem of the example skillset and an executor runs on one robot worker.

- Power cut (`docker kill` of the node container, as pulling the plug) while the tree sleeps: the
  Node turns Unknown once the controller manager's grace period passes, and the instance says
  `RobotReachable=False` with the robot's last-seen time from its Node Lease. Power back
  (`docker start`): the robot boots, `RobotReachable=True`, the same pods (not replaced) run their
  containers again, and the executor, started afresh, runs the tree from its root to SUCCESS.
- Stopped kubelet: the same unreachable report, while the robot's containerd keeps the mission's
  containers running; the kubelet back, nothing restarted and the tree still RUNNING.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

import pytest
from coral_testbed.kind import clusters, faults
from coral_testbed.kind.missions import KindMissionStack
from coral_testbed.waiting import wait_for
from kubernetes import client as k8s
from missions import realsystems as rs

from .fleet import KindCluster, Mission, crictl, ready

pytestmark = [pytest.mark.slow, pytest.mark.ros, pytest.mark.timeout(1800)]

ROBOT = "relay-worker"
ASLEEP_S = 20
# Long enough to cut the power while the tree sleeps; a restarted executor runs it all again.
SLEEP_THEN_WAIT = rs.mission_tree(
    '<Count count="{count}"/>',
    f'<Sleep msec="{ASLEEP_S * 1000}"/>',
    '<WaitForCount threshold="1" timeout_ms="60000"/>',
)
# A mission that outlasts the outage: it waits on the skillset's count topic for ten minutes.
WAIT_LONG = rs.mission_tree(
    '<Count count="{count}"/>', '<WaitForCount threshold="1000" timeout_ms="600000"/>'
)


def _running(
    kind_operator: KindMissionStack, name: str, domain: int, tree: str, active: str
) -> tuple[Mission, dict[str, Any]]:
    """The mission on `ROBOT` once its tree runs `active`, the robot reachable; with its pods."""
    mission = Mission(kind_operator, ROBOT, name, domain, tree)
    mission.running_in(active, timeout=300)
    assert rs.condition(mission.instance(), "RobotReachable")["status"] == "True"
    pods = mission.pods()
    assert set(pods) == {rs.SKILLSET, "executor"}
    return mission, pods


def _same_pods(mission: Mission, before: dict[str, Any]) -> dict[str, Any]:
    """The mission's pods, asserted to be the very pods `before` (same uids), not replacements."""
    pods = mission.pods()
    for component, pod in pods.items():
        assert pod.metadata.uid == before[component].metadata.uid, component
    return pods


@contextmanager
def _robot_away(
    kind_cluster: KindCluster,
    kind_operator: KindMissionStack,
    mission: Mission,
    before: dict[str, Any],
    leave: Callable[[clusters.Running, str], None],
    come_back: Callable[[clusters.Running, str], None],
) -> Iterator[clusters.Running]:
    """`leave` takes `ROBOT` away; the body runs once the robot is reported unreachable with its
    pods `before` kept, and `come_back` follows whatever the body did."""
    running = kind_cluster.running
    node = faults.node_of(running, ROBOT)
    leave(running, ROBOT)
    try:
        _assert_unreachable_with_its_pods(kind_operator, mission, node, before)
        yield running
    finally:
        come_back(running, ROBOT)


def _assert_unreachable_with_its_pods(
    kind_operator: KindMissionStack, mission: Mission, node: str, before: dict[str, Any]
) -> None:
    """Waits for the Node to turn Unknown and the instance to say `RobotReachable=False` with the
    Lease's last renewal as the robot's last-seen time; the pods `before` still bound to it."""
    wait_for(
        lambda: ready(kind_operator.core, node) == "Unknown",
        timeout=120,
        interval=1,
        message=f"{node} to turn NotReady (Unknown)",
    )
    unreachable = wait_for(
        lambda: mission.reachable("False"),
        timeout=60,
        message=lambda: f"RobotReachable=False: {mission.instance()}",
    )
    # Nothing renews the Lease while the robot is away: its last renewal is when it was last heard from.
    leases = k8s.CoordinationV1Api(kind_operator.cluster.api_client)
    renewed = leases.read_namespaced_lease(node, "kube-node-lease").spec.renew_time
    last_seen = renewed.strftime("%Y-%m-%dT%H:%M:%SZ")
    assert unreachable["status"]["robot"]["lastSeen"] == last_seen, unreachable["status"]["robot"]
    condition = rs.condition(unreachable, "RobotReachable")
    assert condition["reason"] == "NodeUnreachable", condition
    assert f"last seen {last_seen}" in condition["message"], condition
    # Neither the operator nor the cluster replaces the pods of a robot that is away.
    for component, pod in _same_pods(mission, before).items():
        assert pod.spec.node_name == node and pod.metadata.deletion_timestamp is None, component


def _reachable_again(mission: Mission, timeout: float) -> dict[str, Any]:
    """The instance once `RobotReachable=True` again, with no last-seen time left."""
    back = wait_for(
        lambda: mission.reachable("True"),
        timeout=timeout,
        message=lambda: f"RobotReachable=True again: {mission.instance()}",
    )
    assert "lastSeen" not in back["status"]["robot"], back["status"]["robot"]
    return back


def test_a_robot_whose_power_is_cut_mid_mission_is_unreachable_then_boots_and_runs_the_tree_again(
    kind_cluster: KindCluster, kind_operator: KindMissionStack, ros_env: dict[str, str]
) -> None:
    domain = int(ros_env["ROS_DOMAIN_ID"])
    mission, before = _running(kind_operator, "power", domain, SLEEP_THEN_WAIT, "Sleep")

    with _robot_away(kind_cluster, kind_operator, mission, before, faults.cut_power, faults.restore_power):
        pass  # Nothing runs on a robot without power: there is nothing more to see while it is off.

    _reachable_again(mission, timeout=180)
    # The boot ended every container: the kubelet starts them again in the same pods, so the
    # executor runs the tree from its root (through the sleep again) to SUCCESS.
    done = wait_for(
        lambda: mission.with_root("SUCCESS", "FAILURE"),
        timeout=ASLEEP_S + 240,
        message=lambda: f"the tree to end: {mission.instance()}\n{mission.logs()}",
    )
    assert rs.tree(done)["rootStatus"] == "SUCCESS", f"{rs.tree(done)}\n{mission.logs()}"
    _same_pods(mission, before)
    restarts = {c["name"]: c["restarts"] for c in done["status"]["components"]}
    assert restarts[rs.SKILLSET] >= 1 and restarts["executor"] >= 1, done["status"]["components"]


def test_a_stopped_kubelet_makes_the_robot_unreachable_with_its_lease_time_and_keeps_its_pods(
    kind_cluster: KindCluster, kind_operator: KindMissionStack, ros_env: dict[str, str]
) -> None:
    domain = int(ros_env["ROS_DOMAIN_ID"])
    mission, before = _running(kind_operator, "patrol", domain, WAIT_LONG, "WaitForCount")

    with _robot_away(
        kind_cluster, kind_operator, mission, before, faults.stop_kubelet, faults.start_kubelet
    ) as running:
        # The containers never stopped: the robot's containerd still runs them while its kubelet is down.
        listed = crictl(running, ROBOT, "ps", "-q").split()
        for component, pod in before.items():
            assert rs.container_id(pod.status.container_statuses[0]) in listed, component

    back = _reachable_again(mission, timeout=90)
    assert rs.tree(back)["rootStatus"] == "RUNNING", rs.tree(back)
    for component, pod in _same_pods(mission, before).items():
        assert pod.status.container_statuses[0].restart_count == 0, component
