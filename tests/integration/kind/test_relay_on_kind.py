"""The relay mission across three kind robots, each its own node container on the cluster's network.

The survey robot maps the bag with SLAM, saves the map on the site share and hands it to the
server, which relays it to the worker, which loads it. Executors run on the host network of their
own robot (its node container's), so DDS between them crosses the kind network. The share is a
host folder bound at `/srv/maps` into every robot's node (`kind_cluster`), as an NFS mount is on a
real site. With the server's link cut (`docker network disconnect`), the survey's `TriggerRemote`
and the worker's `WaitForRemoteTrigger` time out and their Fallback branches run; with the link
restored the next mission passes.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from coral_testbed.kind import faults
from coral_testbed.kind.missions import KindMissionStack
from coral_testbed.missions import following, manifests
from coral_testbed.waiting import wait_for
from kubernetes import client as k8s
from missions.conftest import wait_finished

from .fleet import KindCluster

pytestmark = [pytest.mark.slow, pytest.mark.ros]

SURVEY, SERVER, WORKER = manifests.RELAY_ROBOTS


@pytest.fixture(scope="module")
def survey_bag(kind_missions: KindMissionStack, short_bag: Path) -> None:
    """The short bag on the survey robot, where the mission's bag player reads it."""
    kind_missions.place_bag(SURVEY, short_bag / "bag", manifests.SURVEY_BAG)


@pytest.fixture
def relay(
    kind_cluster: KindCluster, kind_operator: KindMissionStack, survey_bag: None
) -> Iterator[tuple[KindMissionStack, Path]]:
    """The mission view and the share, emptied (the test's systems go with `kind_operator`)."""
    for stale in kind_cluster.share.iterdir():
        stale.unlink()
    yield kind_operator, kind_cluster.share


def _mission(domain: int) -> str:
    return manifests.with_domain(manifests.RELAY_MISSION.read_text(), domain)


def _wait(view: KindMissionStack, robots: list[str]) -> dict[str, dict[str, Any]]:
    return wait_finished(view, robots, timeout=300, operator_log=view.operator_log_tail)


def _assert_relayed(view: KindMissionStack, instances: dict[str, dict[str, Any]], share: Path) -> None:
    roots = {robot: following.tree(i).get("rootStatus") for robot, i in instances.items()}
    assert roots == {SURVEY: "SUCCESS", SERVER: "SUCCESS", WORKER: "SUCCESS"}, roots
    # No fallback was needed: no remote trigger timed out anywhere.
    for robot, instance in instances.items():
        failure = following.tree(instance).get("lastFailure") or {}
        assert "Remote" not in failure.get("path", ""), (robot, failure)
    # The survey's container wrote the map into its /srv/maps: the share every robot sees.
    assert (share / "survey_map.ply").is_file(), sorted(p.name for p in share.iterdir())
    localizer = view.log_tail(WORKER, "localizer", chars=20000)
    assert "Loaded map of" in localizer and "survey_map.ply" in localizer, localizer


@pytest.mark.timeout(900)
def test_relay_mission_runs_to_success_across_three_kind_robots(
    relay: tuple[KindMissionStack, Path], ros_env: dict[str, str]
) -> None:
    view, share = relay
    view.apply(_mission(int(ros_env["ROS_DOMAIN_ID"])))
    instances = _wait(view, list(manifests.RELAY_ROBOTS))
    _assert_relayed(view, instances, share)
    table = view.cluster.kubectl("get", "coralinstances", "-n", view.namespace).stdout
    assert sum("SUCCESS" in line.split() for line in table.splitlines()) == 3, table
    # Each executor ran on its own robot, on that robot's network.
    executors = view.core.list_namespaced_pod(view.namespace, label_selector="coral.dev/role=executor").items
    nodes = {p.spec.node_name: view.core.read_node(p.spec.node_name) for p in executors}
    assert {n.metadata.labels["coral.dev/robot"] for n in nodes.values()} == set(manifests.RELAY_ROBOTS)
    for pod in executors:
        internal = next(
            a.address for a in nodes[pod.spec.node_name].status.addresses if a.type == "InternalIP"
        )
        assert pod.spec.host_network and pod.status.pod_ip == internal, (pod.metadata.name, internal)

    # Each mission is over for good: every executor exits 0 once and is not started again.
    def current() -> list[k8s.V1Pod]:
        return view.core.list_namespaced_pod(view.namespace, label_selector="coral.dev/role=executor").items

    def logs() -> str:
        return "\n".join(f"--- {r}:\n{view.log_tail(r, 'executor', 1500)}" for r in manifests.RELAY_ROBOTS)

    wait_for(
        lambda: all(p.status.phase == "Succeeded" for p in current()),
        timeout=60,
        message=lambda: (
            f"executors Succeeded: {[(p.metadata.name, p.status.phase) for p in current()]}" + logs()
        ),
    )
    restarted = [p.metadata.name for p in current() if p.status.container_statuses[0].restart_count]
    assert not restarted, f"{restarted}\n{logs()}"


@pytest.mark.timeout(1200)
def test_cut_link_times_out_remote_triggers_into_fallbacks_and_restore_lets_the_next_mission_pass(
    kind_cluster: KindCluster, relay: tuple[KindMissionStack, Path], ros_env: dict[str, str]
) -> None:
    view, share = relay
    domain = int(ros_env["ROS_DOMAIN_ID"])
    # The worker would wait 240 s for the server; a shorter wait keeps the test short.
    view.apply(manifests.with_timeout(_mission(domain), "start_inspection", 40000))

    def server_waiting() -> bool:
        return following.tree(view.instance_of(SERVER) or {}).get("rootStatus") == "RUNNING"

    wait_for(server_waiting, timeout=240, message=lambda: f"server tree RUNNING: {view.instance_of(SERVER)}")
    faults.cut_link(kind_cluster.running, SERVER)
    try:
        instances = _wait(view, [SURVEY, WORKER])
        for robot, waiting_node in ((SURVEY, "TriggerRemote"), (WORKER, "WaitForRemoteTrigger")):
            tree = following.tree(instances[robot])
            # The Fallback turned the timeout into SUCCESS through its other branch.
            assert tree["rootStatus"] == "SUCCESS", (robot, tree)
            failure = tree.get("lastFailure") or {}
            assert waiting_node in failure.get("path", ""), (robot, failure)
        # The worker's first branch (load the shared map) never ran: it inspected without the map.
        assert "Loaded map" not in view.log_tail(WORKER, "localizer", chars=20000)
        assert "did not arrive in time" in view.log_tail(WORKER, "executor", chars=200000)
    finally:
        faults.restore_link(kind_cluster.running, SERVER)

    def server_back() -> bool:
        instance = view.instance_of(SERVER) or {}
        robot = (instance.get("status") or {}).get("robot") or {}
        return (
            robot.get("reachable") is True and following.condition(instance, "Ready").get("status") == "True"
        )

    wait_for(
        server_back, timeout=180, message=lambda: f"server reachable and Ready: {view.instance_of(SERVER)}"
    )
    view.delete_systems(timeout=120)
    (share / "survey_map.ply").unlink(missing_ok=True)
    view.apply(_mission(domain))
    instances = _wait(view, list(manifests.RELAY_ROBOTS))
    _assert_relayed(view, instances, share)
