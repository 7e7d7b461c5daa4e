"""The committed SLAM mission on a kind robot: the operator installed by its Helm chart, the bag
player, both skillsets and the executor as containers the robot's containerd pulled from the
cluster's registry, plugins exported through the shared host-path folder (owned by the components'
non-root user), readiness gating the start, the executor writing its tree status with its own
token, and `kubectl logs` for every pod. What `coral demo` shows of it holds too: `kubectl get
coralinstances`, the map and its picture scored against the bag's ground truth and kept after the
robot is gone, the tree drawn in its result's colour, and the finished executor staying Succeeded
(no re-run) on an instance still Ready."""

from __future__ import annotations

from pathlib import Path

import pytest
from coral import tree_picture
from coral.lidar import demo as slam_demo
from coral.lidar import picture
from coral.local.console import outline_of
from coral_testbed.kind import faults
from coral_testbed.kind.missions import KindMissionStack
from coral_testbed.missions import demo as mission_demo
from coral_testbed.missions import following, manifests
from coral_testbed.waiting import wait_for
from fixtures import pictures
from missions import realsystems as rs
from missions.conftest import TEST_SCANS, wait_finished

from .fleet import started_at

pytestmark = [pytest.mark.slow, pytest.mark.ros, pytest.mark.timeout(900)]

SYSTEM = "lidar-slam"


def test_slam_mission_runs_from_images_on_a_kind_robot(
    kind_operator: KindMissionStack,
    slam_robot: str,
    short_bag: Path,
    ros_env: dict[str, str],
    tmp_path: Path,
) -> None:
    view, robot = kind_operator, slam_robot
    text = manifests.rename_robots(manifests.SLAM_MISSION.read_text(), {manifests.SLAM_ROBOT: robot})
    view.apply(manifests.with_domain(text, int(ros_env["ROS_DOMAIN_ID"])))

    instance = wait_finished(view, [robot], timeout=420, operator_log=view.operator_log_tail)[robot]
    assert following.tree(instance)["rootStatus"] == "SUCCESS", following.describe(instance)
    table = view.cluster.kubectl("get", "coralinstances", "-n", view.namespace).stdout
    row = next(line for line in table.splitlines() if robot in line)
    assert "SUCCESS" in row.split(), table

    pods = {p.metadata.labels["coral.dev/component"]: p for p in rs.pods(view.core, view.namespace, SYSTEM)}
    assert set(pods) == {"bag-player", "slam", "snapshot", "executor"}
    node = faults.node_of(view.running, robot)
    for name, pod in pods.items():
        assert pod.spec.node_name == node
        main = pod.status.container_statuses[0]
        # Pulled from the registry through the robot's containerd, by the example's own name.
        assert main.image_id.startswith(("docker.io/coral/", "coral.local/", "127.0.0.1:")), main
        # `kubectl logs` through the robot's kubelet, for every pod.
        view.cluster.kubectl("logs", "-n", view.namespace, pod.metadata.name, "-c", name)
    # Skillsets wrote their plugins as uid 10001 into the root-created host path: the readiness
    # probe (the plugin marker) passed, and only then did the executor start.
    for skillset in ("slam", "snapshot"):
        assert pods[skillset].status.container_statuses[0].ready or pods[skillset].status.phase == "Running"
        assert started_at(pods[skillset].status.container_statuses[0]) <= started_at(
            pods["executor"].status.container_statuses[0]
        )
    executor = pods["executor"]
    # The executor's identity is its own ServiceAccount (the status came through its projected
    # token: no other process of this test writes instance status).
    assert executor.spec.service_account_name not in (None, "default")
    assert following.tree(instance).get("tickCount", 0) > 0, following.tree(instance)
    finished = wait_for(
        lambda: (
            (p := view.core.read_namespaced_pod(executor.metadata.name, view.namespace)).status.phase
            == "Succeeded"
            and p
        ),
        timeout=60,
        message="the executor pod to end Succeeded",
    )
    # The mission is over: the executor is not started again, and the instance says so while it
    # stays Ready (a finished mission is not a broken robot).
    assert finished.status.container_statuses[0].restart_count == 0
    assert finished.spec.restart_policy == "OnFailure"

    def mission_finished() -> bool:
        current = view.instance_of(robot) or {}
        components = {c["name"]: c for c in (current.get("status") or {}).get("components", [])}
        return (
            following.condition(current, "Ready").get("status") == "True"
            and components.get("executor", {}).get("phase") == "Succeeded"
        )

    wait_for(mission_finished, timeout=90, message=lambda: f"mission finished: {view.instance_of(robot)}")

    # The map and trajectory are in the SLAM container's output folder; `kubectl cp` brings them
    # here, and they match the bag's ground truth as they do with `coral run`.
    output = view.component_output(robot, "slam", tmp_path / "output")
    assert output is not None, view.log_tail(robot, "slam")
    evaluation = slam_demo.evaluate(output, short_bag)
    assert evaluation.ground_truth_scans == TEST_SCANS and evaluation.scans >= TEST_SCANS - 2, evaluation
    assert evaluation.map_points > 1000, evaluation
    assert evaluation.error is not None and evaluation.error.ate_rmse_m < 0.5, evaluation.error
    # The picture lands beside the map, as `coral demo` prints it.
    map_file = output / slam_demo.EXAMPLE_MAP_NAME
    assert evaluation.picture_path == map_file.with_suffix(".png")
    rgb = pictures.pixels(evaluation.picture_path, picture.SIZE_PX)
    assert pictures.count_near(rgb, pictures.RED) > 200 and pictures.count_near(rgb, pictures.GREEN) > 200

    # What `coral demo` keeps once the robot is gone: the same files, picture included.
    kept = mission_demo.keep_outputs(evaluation, tmp_path / "kept")
    assert kept.map_path == tmp_path / "kept" / "slam_map.ply" and kept.map_path.is_file()
    assert kept.picture_path is not None
    assert kept.picture_path.read_bytes() == evaluation.picture_path.read_bytes()
    assert (tmp_path / "kept" / "slam_map.trajectory.csv").is_file()

    # `coral demo --tree-png`: the deployed tree, its root in the colour of the mission's result.
    said: list[str] = []
    mission_demo.draw_trees(view, [robot], tmp_path / "tree.png", said.append)
    assert said == [f"Tree picture      : {tmp_path / 'tree.png'}"]
    outline = outline_of(manifests.ROOT / "examples" / "lidar-slam" / "tree.xml")
    rgb = pictures.pixels(tmp_path / "tree.png", tree_picture.size_px(outline), min_ink=0.01)
    green = tuple(int(tree_picture.FILL["SUCCESS"][i : i + 2], 16) for i in (1, 3, 5))
    assert pictures.count_near(rgb, green, 6) > 200
