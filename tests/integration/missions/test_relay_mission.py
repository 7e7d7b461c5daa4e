"""The relay mission across three real robots, each in its own network namespace on the bridge.

The survey robot maps the bag with SLAM, saves the map on the site share and hands it to the
server, which relays it to the worker, which loads it. Executors run on the host network of their
own robot, so DDS between them crosses the robots' links. The share is the server's `/srv/maps`,
mounted at the same path in the survey's and the worker's mount views (an NFS mount on a real
site). With the server's link cut, the survey's `TriggerRemote` and the worker's
`WaitForRemoteTrigger` time out and their Fallback branches run; with the link restored the next
mission passes.

The robots are this module's own (named as in the example), removed at the end of the module,
which fails if any of their processes, mounts, network namespaces, links or cgroups is left.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from coral_testbed.cluster import Cluster, realrobots
from coral_testbed.missions import MissionView, following, manifests
from coral_testbed.missions.stack import operator_policy
from coral_testbed.waiting import wait_for
from fixtures.operator import HelmOperator
from kubernetes import client as k8s

from .conftest import wait_finished

pytestmark = [pytest.mark.cluster, pytest.mark.slow, pytest.mark.ros, pytest.mark.real_robots]

SURVEY, SERVER, WORKER = manifests.RELAY_ROBOTS


@pytest.fixture(scope="module")
def relay_robots(cluster: Cluster, operator_node: str, short_bag: Path) -> Iterator[Path]:
    """The example's three robots, started as real robots with the bag on the survey robot and the
    server's site share mounted on the other two; yields where the share is on this machine."""
    fleet = cluster.robots
    names = list(manifests.RELAY_ROBOTS)
    fleet.add(names)
    layouts = [fleet.layout(name) for name in names]
    try:
        view = MissionView(cluster, "default")
        view.place_bag(SURVEY, short_bag / "bag", manifests.SURVEY_BAG)
        yield view.share_folder(SERVER, [SURVEY, WORKER])
    finally:
        fleet.remove(names)
        left = realrobots.robot_leftovers(layouts)
        assert not left, f"the relay robots left behind: {left}"


@pytest.fixture
def helm_policy(namespace: str) -> dict[str, tuple[str, ...]]:
    """The missions' policy: the host network, and the bags and the site share as host paths."""
    return operator_policy(namespace)


@pytest.fixture
def relay(
    mission: MissionView, relay_robots: Path, helm_operator: HelmOperator
) -> Iterator[tuple[MissionView, Path]]:
    """The mission view and the share, emptied; the test's systems and pods are gone afterwards."""
    for stale in relay_robots.iterdir():
        stale.unlink()
    yield mission, relay_robots
    mission.delete_systems(timeout=120)


def _mission(domain: int) -> str:
    return manifests.with_domain(manifests.RELAY_MISSION.read_text(), domain)


def _wait(view: MissionView, operator: HelmOperator, robots: list[str]) -> dict[str, dict[str, Any]]:
    return wait_finished(view, robots, timeout=300, operator_log=operator.logs)


def _assert_relayed(view: MissionView, instances: dict[str, dict[str, Any]], share: Path) -> None:
    roots = {robot: following.tree(i).get("rootStatus") for robot, i in instances.items()}
    assert roots == {SURVEY: "SUCCESS", SERVER: "SUCCESS", WORKER: "SUCCESS"}, roots
    # No fallback was needed: no remote trigger timed out anywhere.
    for robot, instance in instances.items():
        failure = following.tree(instance).get("lastFailure") or {}
        assert "Remote" not in failure.get("path", ""), (robot, failure)
    # The survey's container wrote the map into its /srv/maps: the server's folder.
    assert (share / "survey_map.ply").is_file(), sorted(p.name for p in share.iterdir())
    localizer = view.log_tail(WORKER, "localizer", chars=20000)
    assert "Loaded map of" in localizer and "survey_map.ply" in localizer, localizer


@pytest.mark.timeout(600)
def test_relay_mission_runs_to_success_across_three_real_robots(
    cluster: Cluster,
    relay: tuple[MissionView, Path],
    helm_operator: HelmOperator,
    ros_env: dict[str, str],
) -> None:
    view, share = relay
    view.apply(_mission(int(ros_env["ROS_DOMAIN_ID"])))
    instances = _wait(view, helm_operator, list(manifests.RELAY_ROBOTS))
    _assert_relayed(view, instances, share)
    table = cluster.kubectl("get", "coralinstances", "-n", view.namespace).stdout
    assert sum("SUCCESS" in line.split() for line in table.splitlines()) == 3, table
    # Each executor ran on its own robot, on that robot's network.
    executors = view.core.list_namespaced_pod(view.namespace, label_selector="coral.dev/role=executor").items
    assert {p.spec.node_name for p in executors} == set(manifests.RELAY_ROBOTS)
    fleet = cluster.robots
    assert all(p.spec.host_network and p.status.pod_ip == fleet.address(p.spec.node_name) for p in executors)

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


@pytest.mark.timeout(900)
def test_cut_link_times_out_remote_triggers_into_fallbacks_and_restore_lets_the_next_mission_pass(
    cluster: Cluster,
    relay: tuple[MissionView, Path],
    helm_operator: HelmOperator,
    ros_env: dict[str, str],
) -> None:
    view, share = relay
    fleet = cluster.robots
    domain = int(ros_env["ROS_DOMAIN_ID"])
    # The worker would wait 240 s for the server; a shorter wait keeps the test short.
    view.apply(manifests.with_timeout(_mission(domain), "start_inspection", 40000))

    def server_waiting() -> bool:
        return following.tree(view.instance_of(SERVER) or {}).get("rootStatus") == "RUNNING"

    wait_for(server_waiting, timeout=240, message=lambda: f"server tree RUNNING: {view.instance_of(SERVER)}")
    fleet.cut_link(SERVER)
    try:
        instances = _wait(view, helm_operator, [SURVEY, WORKER])
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
        fleet.restore_link(SERVER)

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
    instances = _wait(view, helm_operator, list(manifests.RELAY_ROBOTS))
    _assert_relayed(view, instances, share)
