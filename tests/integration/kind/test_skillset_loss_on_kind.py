"""A skillset lost on a kind robot mid-mission: `LibraryDegraded` on the robot's CoralInstance, the
tree's Fallback instead of a wait on the dead skillset, and the way back.

Its container killed: through the CRI (`crictl stop --timeout 0` inside the robot's node), as an
operator of the machine would do it. The kubelet restarts it (restartPolicy Always), the skillset
exports its plugin again, and the executor, still running, calls it again: the library recovers
and `LibraryDegraded` turns False.

The mission's inspection waits on the example skillset's count topic (a long wait, so the fault
lands while the behavior is RUNNING); the Fallback reports instead, then the mission counts again
until the restarted skillset answers.

Its pod deleted, as an eviction or a crash would end it (issue 50: the operator recreated the SLAM
skillset's pod, the new skillset came back without its state, and the tree retried its behavior
400 times a second (rate 20) while the instance read healthy): within 10 s the instance says
`LibraryDegraded`, the tree's Fallback runs, the calls into the new skillset fail until the tree
has been told of the restart, and the mission ends in SUCCESS. The executor's own tick counter
(`status.tree.tickCount`) never runs ahead of the configured rate, though a retry of a call that
fails at once wakes the tree from its own tick.
"""

from __future__ import annotations

import time
from datetime import datetime

import pytest
from coral_testbed.kind.missions import KindMissionStack
from coral_testbed.waiting import wait_for
from missions import realsystems as rs

from .fleet import KindCluster, Mission, crictl

pytestmark = [pytest.mark.slow, pytest.mark.ros, pytest.mark.timeout(1800)]

ROBOT = "relay-survey"
# The pause before counting again lets the Fallback's report reach the instance's status (the
# executor writes it at most once a second) before the retries' failures replace it.
TREE = rs.mission_tree(
    rs.INSPECT_OR_REPORT,
    '<Sleep msec="4000"/>',
    """<RetryUntilSuccessful num_attempts="240">
        <Sequence>
          <Sleep msec="500"/>
          <Count name="CountAgain" count="{count}"/>
        </Sequence>
      </RetryUntilSuccessful>""",
    '<WaitForCount name="Recounted" threshold="1" timeout_ms="30000"/>',
)


def test_killed_skillset_container_degrades_the_instance_falls_back_and_recovers(
    kind_cluster: KindCluster, kind_operator: KindMissionStack, ros_env: dict[str, str]
) -> None:
    running = kind_cluster.running
    mission = Mission(kind_operator, ROBOT, "inspection", int(ros_env["ROS_DOMAIN_ID"]), TREE)
    mission.running_in("WaitForCount", timeout=240)
    pod = mission.pods(rs.SKILLSET)[rs.SKILLSET]
    killed = rs.container_id(pod.status.container_statuses[0])
    # What an operator of the machine sees: the running container, found by its kubelet labels.
    listed = crictl(
        running, ROBOT, "ps", "-q",
        "--label", f"io.kubernetes.pod.namespace={kind_operator.namespace}",
        "--label", f"io.kubernetes.container.name={rs.SKILLSET}",
    ).split()  # fmt: skip
    assert listed == [killed]
    crictl(running, ROBOT, "stop", "--timeout", "0", killed)

    def fell_back() -> dict:
        item = mission.instance()
        failure = rs.tree(item).get("lastFailure") or {}
        return item if "WaitForCount" in failure.get("path", "") else {}

    # The dead skillset's behavior fails at once instead of waiting out its 180 s.
    item = wait_for(fell_back, timeout=60, interval=0.3, message=lambda: f"the Fallback: {mission.logs()}")
    failure = rs.tree(item)["lastFailure"]
    assert rs.SKILLSET in failure["message"], failure
    assert rs.tree(item)["rootStatus"] == "RUNNING", rs.tree(item)

    degraded = wait_for(
        lambda: (c := rs.condition(mission.instance(), "LibraryDegraded")).get("status") == "True" and c,
        timeout=60,
        interval=0.3,
        message=lambda: f"LibraryDegraded=True: {mission.instance()}\n{mission.logs()}",
    )
    assert rs.SKILLSET in degraded["message"], degraded

    # The kubelet restarts the container; the restarted skillset exports its plugin and answers.
    finished = wait_for(
        lambda: mission.with_root("SUCCESS", "FAILURE"),
        timeout=180,
        message=lambda: f"the tree to end: {mission.instance()}\n{mission.logs()}",
    )
    assert rs.tree(finished)["rootStatus"] == "SUCCESS", rs.tree(finished)
    recovered = wait_for(
        lambda: (c := rs.condition(mission.instance(), "LibraryDegraded")).get("status") == "False" and c,
        timeout=60,
        message=lambda: f"LibraryDegraded=False: {mission.instance()}",
    )
    assert recovered["reason"] == "LibrariesHealthy", recovered
    after = mission.pods(rs.SKILLSET)[rs.SKILLSET]
    status = after.status.container_statuses[0]
    assert after.metadata.uid == pod.metadata.uid, "the pod was replaced instead of its container restarted"
    assert status.restart_count >= 1 and rs.container_id(status) != killed, status
    assert status.last_state.terminated is not None and status.last_state.terminated.exit_code == 137


RATE_HZ = 10.0
# No pause between the retries: only the executor's rate bounds them.
RETRY_AT_ONCE = rs.mission_tree(
    rs.INSPECT_OR_REPORT,
    """<RetryUntilSuccessful num_attempts="-1">
        <Count name="CountAgain" count="{count}"/>
      </RetryUntilSuccessful>""",
)


def test_a_deleted_skillset_pod_degrades_the_library_runs_the_fallback_and_keeps_the_rate(
    kind_operator: KindMissionStack, ros_env: dict[str, str]
) -> None:
    mission = Mission(kind_operator, ROBOT, "evicted", int(ros_env["ROS_DOMAIN_ID"]), RETRY_AT_ONCE)
    started = rs.tree(mission.running_in("WaitForCount", timeout=240))
    old = mission.pods(rs.SKILLSET)[rs.SKILLSET]
    kind_operator.core.delete_namespaced_pod(old.metadata.name, kind_operator.namespace)
    deleted = time.monotonic()
    wait_for(
        lambda: rs.condition(mission.instance(), "LibraryDegraded").get("status") == "True",
        timeout=10,
        interval=0.5,
        message=lambda: f"LibraryDegraded within 10 s: {mission.instance()}",
    )
    print(f"LibraryDegraded on the instance {time.monotonic() - deleted:.1f} s after the deletion")
    finished = wait_for(
        lambda: mission.with_root("SUCCESS", "FAILURE"),
        timeout=180,
        message=lambda: f"the mission to end: {mission.instance()}\n{mission.logs()}",
    )
    tree = rs.tree(finished)
    # Without the Fallback, the Inspect sequence's failure would have failed the mission.
    assert tree["rootStatus"] == "SUCCESS", tree
    new = mission.pods(rs.SKILLSET)[rs.SKILLSET]
    assert new.metadata.uid != old.metadata.uid, "the operator made a new skillset pod"
    # The executor's counter against its own clock (second precision on both ends).
    ticks = tree["tickCount"] - started["tickCount"]
    seconds = (
        datetime.fromisoformat(tree["updatedAt"]) - datetime.fromisoformat(started["updatedAt"])
    ).total_seconds()
    assert ticks <= RATE_HZ * (seconds + 2) + 1, f"{ticks} ticks in {seconds:.0f} s at {RATE_HZ:g} Hz"
    print(f"{ticks} ticks in {seconds:.0f} s at {RATE_HZ:g} Hz")
