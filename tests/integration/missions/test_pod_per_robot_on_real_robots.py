"""`examples/lidar-slam` with `layout: PodPerRobot` on a real robot (a real kubelet and containerd).

The kubelet's side of the layout, which kwok cannot show: the mission ends in SUCCESS with the same
CoralInstance status as the default layout; the containers' start times show drivers before
skillsets before the executor; killing the SLAM skillset's container through the robot's CRI
reports `LibraryDegraded` and the tree takes its fallback instead of waiting on the dead skillset;
the kubelet restarts only that container and the library recovers, but the new process lost the
map, so the mission, once asked to stop, ends in FAILURE at `SaveMap` instead of saving nothing.

The operator is installed by Helm (`helm_operator`); the components run from the images in the
session's registry; the short test bag is copied into the robot. Skipped, with its reason, where
real robots or images cannot run here.
"""

from __future__ import annotations

import copy
from datetime import datetime
from pathlib import Path
from typing import Any

import pytest
import yaml
from coral_testbed.cluster import Cluster, realrobots
from coral_testbed.missions import MissionView, manifests
from coral_testbed.waiting import wait_for
from fixtures.operator import HelmOperator
from kubernetes import client as k8s

from .conftest import first_real_robot, real_robot_marks

pytestmark = real_robot_marks(timeout_s=600)

EXAMPLE = "examples/lidar-slam/mission.yaml"
GROUP, VERSION = "coral.dev", "v1alpha1"
COMPARED = ("Ready", "Stalled", "RobotReachable", "ComponentsReady", "PluginsReady", "LibraryDegraded")


@pytest.fixture
def real_robot_name(
    helm_operator: HelmOperator, real_robots: realrobots.RealRobots, mission: MissionView, short_bag: Path
) -> str:
    """The first real robot of the session, with the short bag where the example's driver reads it."""
    robot = first_real_robot(real_robots)
    mission.place_bag(robot, short_bag / "bag", manifests.SLAM_BAG)
    return robot


@pytest.fixture
def domain(ros_env: dict[str, str]) -> int:
    """This test's ROS domain, so no other ROS process on the machine talks to its robot."""
    return int(ros_env["ROS_DOMAIN_ID"])


def _system(root: Any, name: str, robot: str, layout: str, domain: int) -> dict[str, Any]:
    manifest = copy.deepcopy(yaml.safe_load(manifests.with_domain((root / EXAMPLE).read_text(), domain)))
    manifest["metadata"]["name"] = name
    manifest["spec"]["robots"] = {"matchLabels": {"coral.dev/robot": robot}}
    manifest["spec"]["layout"] = layout
    return manifest


def _set_bag_rate(manifest: dict[str, Any], rate: float) -> None:
    """Plays the bag at `rate` times its recorded timing (the bag player's `rate` parameter)."""
    parameters = yaml.safe_load(manifest["spec"]["parameters"]["inline"])
    parameters["bag_player"]["ros__parameters"]["rate"] = rate
    manifest["spec"]["parameters"]["inline"] = yaml.safe_dump(parameters)


def _instance(custom: k8s.CustomObjectsApi, namespace: str, system: str) -> dict[str, Any] | None:
    items = custom.list_namespaced_custom_object(GROUP, VERSION, namespace, "coralinstances")["items"]
    return next((i for i in items if i["spec"]["system"] == system), None)


def _condition(instance: dict[str, Any] | None, ctype: str) -> dict[str, Any]:
    conditions = ((instance or {}).get("status") or {}).get("conditions") or []
    return next((c for c in conditions if c["type"] == ctype), {})


def _finished(custom: k8s.CustomObjectsApi, namespace: str, system: str) -> dict[str, Any] | None:
    instance = _instance(custom, namespace, system)
    tree = ((instance or {}).get("status") or {}).get("tree") or {}
    return instance if tree.get("rootStatus") in ("SUCCESS", "FAILURE") else None


def _finished_and_settled(custom: k8s.CustomObjectsApi, namespace: str, system: str) -> dict[str, Any] | None:
    """Finished, with the operator's conditions caught up. The executor writes the tree's end and
    the operator writes the conditions from the pods, so a mission can finish while its transient
    bag player is still between exiting and `Succeeded` (Ready False, `WaitingForDrivers`, for a
    moment): the layouts are compared once Ready says True."""
    instance = _finished(custom, namespace, system)
    return instance if _condition(instance, "Ready").get("status") == "True" else None


def _summary(instance: dict[str, Any]) -> dict[str, Any]:
    status = instance["status"]
    return {
        "tree": status["tree"]["rootStatus"],
        "conditions": {
            c["type"]: (c["status"], c["reason"]) for c in status["conditions"] if c["type"] in COMPARED
        },
        "components": [(c["name"], c["role"]) for c in status["components"]],
        "plugins": sorted((status.get("plugins") or {}).get("loaded") or []),
    }


def _run(cluster: Cluster, namespace: str, manifest: dict[str, Any]) -> dict[str, Any]:
    custom = k8s.CustomObjectsApi(cluster.api_client)
    custom.create_namespaced_custom_object(GROUP, VERSION, namespace, "coralsystems", manifest)
    name = manifest["metadata"]["name"]
    instance = wait_for(
        lambda: _finished_and_settled(custom, namespace, name),
        timeout=420,
        message=f"{name}'s tree to finish and its instance to be Ready",
    )
    custom.delete_namespaced_custom_object(GROUP, VERSION, namespace, "coralsystems", name)
    return instance


def _started(status: Any) -> datetime:
    state = status.state
    running = state.running or state.terminated
    assert running is not None and running.started_at is not None, f"{status.name} never started"
    return running.started_at


def test_lidar_slam_in_one_pod_per_robot_reads_like_the_default_layout(
    cluster: Cluster, namespace: str, real_robot_name: str, domain: int, pytestconfig: pytest.Config
) -> None:
    root = pytestconfig.rootpath
    first = _system(root, "slam-default", real_robot_name, "PodPerComponent", domain)
    default = _run(cluster, namespace, first)
    core = k8s.CoreV1Api(cluster.api_client)
    custom = k8s.CustomObjectsApi(cluster.api_client)
    # The operator's own pod lives in this namespace too; only the mission's pods must go.
    wait_for(
        lambda: not core.list_namespaced_pod(namespace, label_selector="coral.dev/system=slam-default").items,
        timeout=120,
        message="the first system's pods to go",
    )

    manifest = _system(root, "slam-one-pod", real_robot_name, "PodPerRobot", domain)
    custom.create_namespaced_custom_object(GROUP, VERSION, namespace, "coralsystems", manifest)
    one_pod = wait_for(
        lambda: _finished_and_settled(custom, namespace, "slam-one-pod"),
        timeout=420,
        message="the one-pod tree to finish and its instance to be Ready",
    )
    assert one_pod["status"]["tree"]["rootStatus"] == "SUCCESS"
    assert _summary(one_pod) == _summary(default)

    (pod,) = core.list_namespaced_pod(namespace, label_selector="coral.dev/system=slam-one-pod").items
    sidecars = {s.name: _started(s) for s in pod.status.init_container_statuses}
    mains = {s.name: _started(s) for s in pod.status.container_statuses}
    # Sidecars start in compose order, each once the previous one's startup probe passed; the
    # transient bag player runs beside the executor, so it starts after every skillset.
    assert sidecars["slam"] <= sidecars["snapshot"]
    assert max(sidecars.values()) <= mains["executor"]
    assert max(sidecars.values()) <= mains["bag-player"]


# Published from inside the pod (its ROS domain and network): the example's
# documented way to end its mission early (`ros2 topic pub -1 /slam/stop std_msgs/msg/Empty`).
STOP_REQUEST = """
import time
import rclpy
from rclpy.duration import Duration
from std_msgs.msg import Empty
rclpy.init()
node = rclpy.create_node("stop_request")
publisher = node.create_publisher(Empty, "/slam/stop", 10)
deadline = time.monotonic() + 30
while publisher.get_subscription_count() == 0:
    if time.monotonic() > deadline:
        raise SystemExit("the executor never subscribed to /slam/stop")
    rclpy.spin_once(node, timeout_sec=0.1)
publisher.publish(Empty())
publisher.wait_for_all_acked(Duration(seconds=10))
"""


def test_a_killed_slam_container_degrades_the_library_and_the_tree_falls_back(
    cluster: Cluster,
    namespace: str,
    real_robots: realrobots.RealRobots,
    real_robot_name: str,
    domain: int,
    pytestconfig: pytest.Config,
) -> None:
    core = k8s.CoreV1Api(cluster.api_client)
    custom = k8s.CustomObjectsApi(cluster.api_client)
    manifest = _system(pytestconfig.rootpath, "slam-kill", real_robot_name, "PodPerRobot", domain)
    # The short bag lasts 4 s at its recorded rate: a loaded machine could report the loop and
    # reach the container after the data ran out, and the kill would land in EndSLAM instead.
    # At a tenth of the rate the loop lasts 40 s; the stop request below ends it sooner.
    _set_bag_rate(manifest, 0.1)
    custom.create_namespaced_custom_object(GROUP, VERSION, namespace, "coralsystems", manifest)

    def current() -> dict[str, Any]:
        return _instance(custom, namespace, "slam-kill") or {}

    def iterating() -> bool:
        tree = (current().get("status") or {}).get("tree") or {}
        return tree.get("rootStatus") == "RUNNING" and "IterateSLAM" in tree.get("activePath", "")

    wait_for(iterating, timeout=300, message=lambda: f"the mission to iterate: {current()}")
    (pod,) = core.list_namespaced_pod(namespace, label_selector="coral.dev/system=slam-kill").items
    # Killed through the robot's CRI, as an operator of the node would: SIGKILL, no clean shutdown.
    (killed,) = real_robots.cri(
        real_robot_name, "ps", "-q",
        "--label", f"io.kubernetes.pod.name={pod.metadata.name}",
        "--label", "io.kubernetes.container.name=slam",
    ).stdout.split()  # fmt: skip
    real_robots.cri(real_robot_name, "stop", "--timeout", "0", killed)

    seen: dict[str, dict[str, Any]] = {}

    def fell_back() -> bool:
        # The two show up in separate status writes, and the degraded spell lasts seconds.
        item = current()
        failure = ((item.get("status") or {}).get("tree") or {}).get("lastFailure") or {}
        if _condition(item, "LibraryDegraded").get("status") == "True":
            seen.setdefault("degraded", _condition(item, "LibraryDegraded"))
        if "slam is unavailable" in failure.get("message", ""):
            seen.setdefault("failure", failure)
        return len(seen) == 2

    # The SLAM behaviors fail at once, so the loop's Fallback goes on instead of waiting on them.
    wait_for(fell_back, timeout=90, interval=0.3, message=lambda: f"the fallback ({seen}): {current()}")
    assert "slam" in seen["degraded"]["message"], seen
    assert "IterateSLAM" in seen["failure"]["path"], seen

    # The kubelet restarts only the SLAM sidecar; the library recovers. The new process has lost
    # the map and its localization is off, so the loop now fails on the skillset's answer.
    recovered = wait_for(
        lambda: (i := current()) and _condition(i, "LibraryDegraded").get("status") == "False" and i,
        timeout=120,
        message=lambda: f"LibraryDegraded=False: {current()}",
    )
    assert recovered["status"]["tree"]["rootStatus"] == "RUNNING"
    restarted = core.read_namespaced_pod(pod.metadata.name, namespace)
    slam = next(s for s in restarted.status.init_container_statuses if s.name == "slam")
    assert slam.restart_count >= 1 and slam.container_id.rpartition("://")[2] != killed
    others = [*restarted.status.init_container_statuses, *restarted.status.container_statuses]
    assert all(s.restart_count == 0 for s in others if s.name != "slam"), others
    wait_for(
        lambda: (
            "localization is disabled"
            in (((current().get("status") or {}).get("tree") or {}).get("lastFailure") or {}).get(
                "message", ""
            )
        ),
        timeout=60,
        message=lambda: f"the restarted skillset's refusal in the status: {current()}",
    )

    # From the snapshot sidecar: the request ends the tree, the executor's container then exits
    # and the kubelet stops the sidecars, which may cut this process short once it has published.
    request = cluster.kubectl(
        "exec", "-n", namespace, pod.metadata.name, "-c", "snapshot", "--", "python", "-c", STOP_REQUEST,
        timeout=90, check=False,
    )  # fmt: skip
    finished = wait_for(
        lambda: _finished(custom, namespace, "slam-kill"),
        timeout=120,
        message=lambda: f"the tree to end after the stop request ({request.returncode}: {request.stderr})",
    )
    tree = finished["status"]["tree"]
    # The map died with the killed process: the mission says so instead of saving an empty one.
    assert tree["rootStatus"] == "FAILURE", tree
    assert "SaveMap" in tree["lastFailure"]["path"] and "no map to save" in tree["lastFailure"]["message"], (
        tree
    )
