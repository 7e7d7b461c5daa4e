"""`examples/lidar-slam` with `layout: PodPerRobot` on a kind robot (a real kubelet and containerd).

The kubelet's side of the layout, which kwok cannot show: the mission ends in SUCCESS with the same
CoralInstance status as the default layout; the containers' start times show drivers before
skillsets before the executor; killing the SLAM skillset's container through the robot's CRI
(`crictl` in its node) reports `LibraryDegraded` and the tree takes its fallback instead of waiting
on the dead skillset; the kubelet restarts only that container and the library recovers, but the
new process lost the map, so the mission, once asked to stop, ends in FAILURE at `SaveMap` instead
of saving nothing.

The operator is the chart's (`kind_operator`); the components run from the images in the
cluster's registry; the short test bag is copied into the robot's node (`slam_robot`).
"""

from __future__ import annotations

from typing import Any

import pytest
import yaml
from coral_testbed.kind.missions import KindMissionStack
from coral_testbed.missions import manifests
from coral_testbed.waiting import wait_for
from missions import realsystems as rs

from .fleet import crictl, started_at

pytestmark = [pytest.mark.slow, pytest.mark.ros, pytest.mark.timeout(1200)]

COMPARED = ("Ready", "Stalled", "RobotReachable", "ComponentsReady", "PluginsReady", "LibraryDegraded")


def _system(name: str, robot: str, layout: str, domain: int) -> dict[str, Any]:
    manifest = yaml.safe_load(manifests.with_domain(manifests.SLAM_MISSION.read_text(), domain))
    manifest["metadata"]["name"] = name
    manifest["spec"]["robots"] = {"matchLabels": {"coral.dev/robot": robot}}
    manifest["spec"]["layout"] = layout
    return manifest


def _set_bag_rate(manifest: dict[str, Any], rate: float) -> None:
    """Plays the bag at `rate` times its recorded timing (the bag player's `rate` parameter)."""
    parameters = yaml.safe_load(manifest["spec"]["parameters"]["inline"])
    parameters["bag_player"]["ros__parameters"]["rate"] = rate
    manifest["spec"]["parameters"]["inline"] = yaml.safe_dump(parameters)


def _finished(view: KindMissionStack, system: str) -> dict[str, Any]:
    """The system's instance once its tree ended, else {}."""
    return rs.with_root(view.custom, view.namespace, system, "SUCCESS", "FAILURE")


def _finished_and_settled(view: KindMissionStack, system: str) -> dict[str, Any]:
    """Finished, with the operator's conditions caught up. The executor writes the tree's end and
    the operator writes the conditions from the pods, so a mission can finish while its transient
    bag player is still between exiting and `Succeeded` (Ready False, `WaitingForDrivers`, for a
    moment): the layouts are compared once Ready says True."""
    instance = _finished(view, system)
    return instance if rs.condition(instance, "Ready").get("status") == "True" else {}


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


def _run_settled(view: KindMissionStack, manifest: dict[str, Any]) -> dict[str, Any]:
    """Creates the system; its instance once its tree finished and the instance is Ready."""
    rs.create(view.custom, view.namespace, manifest)
    name = manifest["metadata"]["name"]
    return wait_for(
        lambda: _finished_and_settled(view, name),
        timeout=420,
        message=lambda: f"{name}'s tree to finish, Ready: {rs.instance(view.custom, view.namespace, name)}",
    )


def test_lidar_slam_in_one_pod_per_robot_reads_like_the_default_layout(
    kind_operator: KindMissionStack, slam_robot: str, ros_env: dict[str, str]
) -> None:
    view, domain = kind_operator, int(ros_env["ROS_DOMAIN_ID"])
    default = _run_settled(view, _system("slam-default", slam_robot, "PodPerComponent", domain))
    rs.delete(view.custom, view.namespace, "slam-default")
    # The operator's own pod lives in this namespace too; only the mission's pods must go.
    wait_for(
        lambda: not rs.pods(view.core, view.namespace, "slam-default"),
        timeout=120,
        message="the first system's pods to go",
    )

    one_pod = _run_settled(view, _system("slam-one-pod", slam_robot, "PodPerRobot", domain))
    assert one_pod["status"]["tree"]["rootStatus"] == "SUCCESS"
    assert _summary(one_pod) == _summary(default)

    (pod,) = rs.pods(view.core, view.namespace, "slam-one-pod")
    sidecars = {s.name: started_at(s) for s in pod.status.init_container_statuses}
    mains = {s.name: started_at(s) for s in pod.status.container_statuses}
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
    kind_operator: KindMissionStack, slam_robot: str, ros_env: dict[str, str]
) -> None:
    view = kind_operator
    manifest = _system("slam-kill", slam_robot, "PodPerRobot", int(ros_env["ROS_DOMAIN_ID"]))
    # The short bag lasts 4 s at its recorded rate: a loaded machine could report the loop and
    # reach the container after the data ran out, and the kill would land in EndSLAM instead.
    # At a tenth of the rate the loop lasts 40 s; the stop request below ends it sooner.
    _set_bag_rate(manifest, 0.1)
    rs.create(view.custom, view.namespace, manifest)

    def current() -> dict[str, Any]:
        return rs.instance(view.custom, view.namespace, "slam-kill")

    def iterating() -> bool:
        tree = rs.tree(current())
        return tree.get("rootStatus") == "RUNNING" and "IterateSLAM" in tree.get("activePath", "")

    wait_for(iterating, timeout=300, message=lambda: f"the mission to iterate: {current()}")
    (pod,) = rs.pods(view.core, view.namespace, "slam-kill")
    # Killed through the robot's CRI, as an operator of the node would: SIGKILL, no clean shutdown.
    (killed,) = crictl(
        view.running, slam_robot, "ps", "-q",
        "--label", f"io.kubernetes.pod.name={pod.metadata.name}",
        "--label", "io.kubernetes.container.name=slam",
    ).split()  # fmt: skip
    crictl(view.running, slam_robot, "stop", "--timeout", "0", killed)

    seen: dict[str, dict[str, Any]] = {}

    def fell_back() -> bool:
        # The two show up in separate status writes, and the degraded spell lasts seconds.
        item = current()
        failure = rs.tree(item).get("lastFailure") or {}
        if rs.condition(item, "LibraryDegraded").get("status") == "True":
            seen.setdefault("degraded", rs.condition(item, "LibraryDegraded"))
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
        lambda: (i := current()) and rs.condition(i, "LibraryDegraded").get("status") == "False" and i,
        timeout=120,
        message=lambda: f"LibraryDegraded=False: {current()}",
    )
    assert recovered["status"]["tree"]["rootStatus"] == "RUNNING"
    restarted = view.core.read_namespaced_pod(pod.metadata.name, view.namespace)
    slam = next(s for s in restarted.status.init_container_statuses if s.name == "slam")
    assert slam.restart_count >= 1 and rs.container_id(slam) != killed
    others = [*restarted.status.init_container_statuses, *restarted.status.container_statuses]
    assert all(s.restart_count == 0 for s in others if s.name != "slam"), others
    wait_for(
        lambda: (
            "localization is disabled" in (rs.tree(current()).get("lastFailure") or {}).get("message", "")
        ),
        timeout=60,
        message=lambda: f"the restarted skillset's refusal in the status: {current()}",
    )

    # From the snapshot sidecar: the request ends the tree, the executor's container then exits
    # and the kubelet stops the sidecars, which may cut this process short once it has published.
    request = view.cluster.kubectl(
        "exec", "-n", view.namespace, pod.metadata.name, "-c", "snapshot", "--", "python", "-c", STOP_REQUEST,
        timeout=90, check=False,
    )  # fmt: skip
    finished = wait_for(
        lambda: _finished(view, "slam-kill"),
        timeout=120,
        message=lambda: f"the tree to end after the stop request ({request.returncode}: {request.stderr})",
    )
    tree = finished["status"]["tree"]
    # The map died with the killed process: the mission says so instead of saving an empty one.
    assert tree["rootStatus"] == "FAILURE", tree
    assert "SaveMap" in tree["lastFailure"]["path"] and "no map to save" in tree["lastFailure"]["message"], (
        tree
    )
