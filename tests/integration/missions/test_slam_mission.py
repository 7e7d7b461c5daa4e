"""Acceptance 1: the committed SLAM mission, applied with `kubectl apply`, runs to SUCCESS on a
runner robot, `kubectl get coralinstances` shows it, the map is in the robot's files and the
trajectory matches the bag's ground truth; the finished executor stays Succeeded (no re-run).
"""

from __future__ import annotations

from pathlib import Path

import pytest
from coral import tree_picture
from coral.lidar import demo as slam_demo
from coral.lidar import picture
from coral.local.console import outline_of
from coral_testbed.cluster import Cluster
from coral_testbed.missions import demo as mission_demo
from coral_testbed.missions import following, manifests
from coral_testbed.waiting import wait_for
from fixtures import pictures
from kubernetes import client as k8s

from .conftest import TEST_SCANS, StartStack, wait_finished

pytestmark = [pytest.mark.cluster, pytest.mark.slow, pytest.mark.ros, pytest.mark.timeout(420)]


def test_slam_mission_applied_with_kubectl_maps_the_bag(
    cluster: Cluster,
    namespace: str,
    start_stack: StartStack,
    suffix: str,
    short_bag: Path,
    ros_env: dict[str, str],
    tmp_path: Path,
) -> None:
    robot = f"m-slam-{suffix}"
    stack = start_stack([robot])
    assert stack.runner is not None
    manifests.place_bag(stack.runner, robot, short_bag / "bag", manifests.SLAM_BAG)
    text = manifests.rename_robots(manifests.SLAM_MISSION.read_text(), {manifests.SLAM_ROBOT: robot})
    text = manifests.with_domain(text, int(ros_env["ROS_DOMAIN_ID"]))
    cluster.kubectl("apply", "-n", namespace, "-f", "-", input=text)

    instance = wait_finished(stack, [robot], timeout=300)[robot]
    assert following.tree(instance)["rootStatus"] == "SUCCESS", following.describe(instance)

    table = cluster.kubectl("get", "coralinstances", "-n", namespace).stdout
    row = next(line for line in table.splitlines() if robot in line)
    assert "SUCCESS" in row.split(), table

    output = stack.pod_dir(robot, "slam")
    assert output is not None and stack.runner.robot_dir(robot) in output.parents
    map_file = output / slam_demo.EXAMPLE_MAP_NAME
    assert map_file.is_file(), sorted(p.name for p in output.iterdir())
    evaluation = slam_demo.evaluate(output, short_bag)
    assert evaluation.ground_truth_scans == TEST_SCANS and evaluation.scans >= TEST_SCANS - 2, evaluation
    assert evaluation.map_points > 1000
    assert evaluation.error is not None and evaluation.error.ate_rmse_m < 0.5, evaluation.error
    # The picture lands beside the map in the robot's files, as `coral demo` prints it.
    assert evaluation.picture_path == map_file.with_suffix(".png")
    rgb = pictures.pixels(evaluation.picture_path, picture.SIZE_PX)
    assert pictures.count_near(rgb, pictures.RED) > 200 and pictures.count_near(rgb, pictures.GREEN) > 200

    # What `coral demo` keeps once the robot's files are gone: the same files, picture included.
    kept = mission_demo.keep_outputs(evaluation, tmp_path / "kept")
    assert kept.map_path == tmp_path / "kept" / "slam_map.ply" and kept.map_path.is_file()
    assert kept.picture_path is not None
    assert kept.picture_path.read_bytes() == evaluation.picture_path.read_bytes()
    assert (tmp_path / "kept" / "slam_map.trajectory.csv").is_file()

    # `coral demo --tree-png`: the deployed tree, its root in the colour of the mission's result.
    said: list[str] = []
    mission_demo.draw_trees(stack, [robot], tmp_path / "tree.png", said.append)
    assert said == [f"Tree picture      : {tmp_path / 'tree.png'}"]
    outline = outline_of(manifests.ROOT / "examples" / "lidar-slam" / "tree.xml")
    rgb = pictures.pixels(tmp_path / "tree.png", tree_picture.size_px(outline), min_ink=0.01)
    green = tuple(int(tree_picture.FILL["SUCCESS"][i : i + 2], 16) for i in (1, 3, 5))
    assert pictures.count_near(rgb, green, 6) > 200

    # The mission is over: the executor pod ends Succeeded and is not started again.
    core = k8s.CoreV1Api(cluster.api_client)

    def executor_pod() -> k8s.V1Pod:
        return core.list_namespaced_pod(namespace, label_selector="coral.dev/role=executor").items[0]

    pod = wait_for(
        lambda: (p := executor_pod()).status.phase == "Succeeded" and p,
        timeout=60,
        message="executor pod Succeeded",
    )
    assert pod.status.container_statuses[0].restart_count == 0
    assert pod.spec.restart_policy == "OnFailure"

    def mission_finished() -> bool:
        # The instance says the mission ended: executor Succeeded and still Ready (a finished
        # mission is not a broken robot).
        current = stack.instance_of(robot) or {}
        components = {c["name"]: c for c in (current.get("status") or {}).get("components", [])}
        return (
            following.condition(current, "Ready").get("status") == "True"
            and components.get("executor", {}).get("phase") == "Succeeded"
        )

    wait_for(mission_finished, timeout=90, message=lambda: f"mission finished: {stack.instance_of(robot)}")
