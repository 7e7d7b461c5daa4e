"""A skillset pod deleted mid-mission on a real robot, as an eviction or a crash would end it.

Issue 50: the operator recreated the SLAM skillset's pod, the new skillset came back without its
state, and the tree retried its behavior 400 times a second (rate 20) while the instance read
healthy. Here the example skillset's pod is deleted while the tree waits on it: within 10 s the
instance says `LibraryDegraded`, the tree's Fallback runs, the calls into the new skillset fail
until the tree has been told of the restart, and the mission ends in SUCCESS. The executor's own
tick counter (`status.tree.tickCount`) never runs ahead of the configured rate, though a retry
of a call that fails at once wakes the tree from its own tick.
"""

from __future__ import annotations

import time
from datetime import datetime

import pytest
from coral_testbed.cluster import Cluster, realrobots
from coral_testbed.waiting import wait_for
from fixtures.operator import OperatorProcess
from fixtures.robots import REAL_ROBOT_MARKS
from kubernetes import client as k8s

from . import realsystems as rs
from .conftest import first_real_robot

pytestmark = [*REAL_ROBOT_MARKS, pytest.mark.timeout(480)]

SYSTEM = "evicted"
RATE_HZ = 10.0
TREE = rs.mission_tree(
    rs.INSPECT_OR_REPORT,
    """<RetryUntilSuccessful num_attempts="-1">
        <Count name="CountAgain" count="{count}"/>
      </RetryUntilSuccessful>""",
)


def _degraded(item: dict) -> bool:
    return rs.condition(item, "LibraryDegraded").get("status") == "True"


def test_a_deleted_skillset_pod_degrades_the_library_runs_the_fallback_and_keeps_the_rate(
    cluster: Cluster,
    namespace: str,
    built_images: dict,
    real_robots: realrobots.RealRobots,
    coral_operator: OperatorProcess,
    ros_env: dict[str, str],
) -> None:
    robot = first_real_robot(real_robots)
    core, custom = k8s.CoreV1Api(cluster.api_client), k8s.CustomObjectsApi(cluster.api_client)
    system = rs.system(SYSTEM, robot, int(ros_env["ROS_DOMAIN_ID"]), TREE)
    system["spec"]["tree"]["tickRateHz"] = RATE_HZ
    rs.create(custom, namespace, system)
    wait_for(
        lambda: "WaitForCount" in rs.tree(rs.instance(custom, namespace, SYSTEM)).get("activePath", ""),
        timeout=240,
        interval=1,
        message=lambda: f"the tree waiting on the skillset: {rs.instance(custom, namespace, SYSTEM)}",
    )
    started = rs.tree(rs.instance(custom, namespace, SYSTEM))
    (old,) = rs.pods(core, namespace, SYSTEM, rs.SKILLSET)
    core.delete_namespaced_pod(old.metadata.name, namespace)
    deleted = time.monotonic()
    wait_for(
        lambda: _degraded(rs.instance(custom, namespace, SYSTEM)),
        timeout=10,
        interval=0.5,
        message=lambda: f"LibraryDegraded within 10 s: {rs.instance(custom, namespace, SYSTEM)}",
    )
    print(f"LibraryDegraded on the instance {time.monotonic() - deleted:.1f} s after the deletion")
    finished = wait_for(
        lambda: rs.with_root(custom, namespace, SYSTEM, "SUCCESS", "FAILURE"),
        timeout=180,
        interval=1,
        message=lambda: f"the mission to end: {rs.instance(custom, namespace, SYSTEM)}",
    )
    tree = rs.tree(finished)
    # Without the Fallback, the Inspect sequence's failure would have failed the mission.
    assert tree["rootStatus"] == "SUCCESS", tree
    (new,) = rs.pods(core, namespace, SYSTEM, rs.SKILLSET)
    assert new.metadata.uid != old.metadata.uid, "the operator made a new skillset pod"
    # The executor's counter against its own clock (second precision on both ends).
    ticks = tree["tickCount"] - started["tickCount"]
    seconds = (
        datetime.fromisoformat(tree["updatedAt"]) - datetime.fromisoformat(started["updatedAt"])
    ).total_seconds()
    assert ticks <= RATE_HZ * (seconds + 2) + 1, f"{ticks} ticks in {seconds:.0f} s at {RATE_HZ:g} Hz"
    print(f"{ticks} ticks in {seconds:.0f} s at {RATE_HZ:g} Hz")
    rs.delete(custom, namespace, SYSTEM)
