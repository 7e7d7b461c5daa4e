"""`coral run` on the LiDAR SLAM example: the mission succeeds, saves a map, tracks ground truth."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import pytest
import yaml
from coral import tree_picture
from coral.lidar import demo, picture
from coral.local.console import outline_of
from coral_testbed.waiting import wait_for
from fixtures import pictures
from run_helpers import StartRun, alive, component_pids, node_successes, run_records

# Measured on this 40-scan bag through Coral: 0.04 m (the same as KISS-ICP's own pipeline).
ATE_BOUND_M = 0.25

pytestmark = [pytest.mark.ros, pytest.mark.slow]


def test_the_example_mission_ends_in_success_with_a_map_and_a_small_trajectory_error(
    start_run: StartRun,
    run_env: dict[str, str],
    example_copy: Callable[..., Path],
    short_bag: Path,
    tmp_path: Path,
) -> None:
    example = example_copy(rate=2.0)
    output = tmp_path / "out"
    process = start_run(example, output, "--tree-png", str(tmp_path / "tree.png"))
    log, _ = process.communicate(timeout=240)
    assert process.returncode == 0, log
    assert "tree SUCCESS" in log and "Executor executor finished: tree SUCCESS, exit code 0" in log

    evaluation = demo.evaluate(output, short_bag)
    assert evaluation.scans == evaluation.ground_truth_scans == 40
    assert evaluation.map_points > 1000 and (output / "slam_map.ply").stat().st_size > 12 * 1000
    assert evaluation.error is not None and evaluation.error.ate_rmse_m < ATE_BOUND_M
    # The picture beside the map shows the map, the estimate (red) over the ground truth (green).
    assert evaluation.picture_path == output / "slam_map.png"
    rgb = pictures.pixels(evaluation.picture_path, picture.SIZE_PX)
    assert pictures.count_near(rgb, pictures.RED) > 200 and pictures.count_near(rgb, pictures.GREEN) > 200
    assert list((output / "snapshots").glob("snapshot-*/snapshot.json"))

    # The tree picture: the SLAM nodes in the colours of their last results, the path printed.
    assert f"Tree picture: {tmp_path / 'tree.png'}" in log
    outline = outline_of(example / "tree.xml")
    rgb = pictures.pixels(tmp_path / "tree.png", tree_picture.size_px(outline), min_ink=0.01)
    green, red = (
        tuple(int(tree_picture.FILL[s][i : i + 2], 16) for i in (1, 3, 5)) for s in ("SUCCESS", "FAILURE")
    )
    assert pictures.count_near(rgb, green, 6) > 1000  # most nodes succeeded last
    assert pictures.count_near(rgb, red, 6) > 100  # ForceFailure and the iteration it wraps failed

    record = run_records(run_env)[0]
    assert record["state"] == "finished" and record["exit_code"] == 0
    assert not [pid for pid in component_pids(run_env) if alive(pid)]


def test_the_mission_ends_when_another_node_listens_to_the_bags_topics_from_the_start(
    start_run: StartRun,
    run_env: dict[str, str],
    example_copy: Callable[..., Path],
    short_bag: Path,
    tmp_path: Path,
) -> None:
    """A recorder or a viewer on /ground_truth may let the bag start before the tree asks for its
    first snapshot: the snapshot still holds the bag's first messages, and the mission ends."""
    import rclpy
    from nav_msgs.msg import Odometry

    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        node = rclpy.create_node("ground_truth_viewer", context=context)
        node.create_subscription(Odometry, "/ground_truth", lambda _message: None, 10)
        output = tmp_path / "out"
        process = start_run(example_copy(rate=2.0), output)
        log, _ = process.communicate(timeout=240)
        node.destroy_node()
    finally:
        rclpy.shutdown(context=context)
    assert process.returncode == 0, log
    assert len(list((output / "snapshots").glob("snapshot-*/snapshot.json"))) == 1
    evaluation = demo.evaluate(output, short_bag, draw=False)
    assert evaluation.scans == evaluation.ground_truth_scans == 40


def test_a_stop_signal_ends_the_mission_early_with_the_map_saved(
    start_run: StartRun,
    run_env: dict[str, str],
    example_copy: Callable[..., Path],
    short_bag: Path,
    tmp_path: Path,
) -> None:
    import rclpy
    from std_msgs.msg import Empty

    example = example_copy(rate=0.2)  # 40 scans over 20 s: stopped long before the data ends
    output = tmp_path / "out"
    process = start_run(example, output)
    # Two ProcessScan successes mean at least two registered scans, the fewest a trajectory
    # error can be computed from; a stop sent earlier would leave nothing to score.
    wait_for(
        lambda: node_successes(run_env, "ProcessScan") >= 2,
        timeout=120,
        message="the mission to have processed scans",
    )
    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        node = rclpy.create_node("stop_sender", context=context)
        publisher = node.create_publisher(Empty, "/slam/stop", 10)
        # Publish until the run ends: the executor's subscription may need a moment to match.
        wait_for(
            lambda: publisher.publish(Empty()) or process.poll() is not None,
            timeout=60,
            interval=0.2,
            message="the mission to stop",
        )
        node.destroy_node()
    finally:
        rclpy.shutdown(context=context)
    log, _ = process.communicate(timeout=60)
    assert process.returncode == 0, log
    evaluation = demo.evaluate(output, short_bag, draw=False)
    assert 0 < evaluation.scans < evaluation.ground_truth_scans and evaluation.map_points > 0
    assert evaluation.error is not None and evaluation.error.ate_rmse_m < ATE_BOUND_M


def test_a_burst_of_scans_is_registered_as_it_arrives_and_handed_to_the_tree_in_batches(
    start_run: StartRun,
    run_env: dict[str, str],
    example_copy: Callable[..., Path],
    short_bag: Path,
    tmp_path: Path,
) -> None:
    example = example_copy(rate=0.0)  # the whole bag at once: a backlog for the skillset
    params = yaml.safe_load((example / "params.yaml").read_text())
    params["slam"]["ros__parameters"]["subscribe_on_enable"] = True
    (example / "params.yaml").write_text(yaml.safe_dump(params))
    output = tmp_path / "out"
    process = start_run(example, output)
    log, _ = process.communicate(timeout=240)
    assert process.returncode == 0, log

    evaluation = demo.evaluate(output, short_bag, draw=False)
    assert evaluation.scans == evaluation.ground_truth_scans == 40
    assert evaluation.error is not None and evaluation.error.ate_rmse_m < ATE_BOUND_M
    stats = json.loads((output / "slam_map.stats.json").read_text())
    assert stats["processed"] == stats["delivered"] == 40 and stats["failed"] == 0
    # Subscribed at EnableLocalization: the bag player waited for it, so the scans did not pile up
    # before registration started.
    assert stats["queued_at_start"] < 40
    # The tree took the backlog in batches of up to scans_per_call, not one call a scan.
    batch = params["slam"]["ros__parameters"]["scans_per_call"]
    assert 40 / batch <= stats["process_calls"] <= 20
    # A call filling its batch is woken when the batch is full or the backlog registered, not after
    # every scan: each wake-up while registration holds the interpreter lock costs it a preemption.
    assert stats["batch_wakeups"] <= stats["process_calls"] + 2
    assert 0 < stats["registering_s"] <= stats["active_s"]
