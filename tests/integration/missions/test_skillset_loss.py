"""A skillset container killed on a real robot mid-mission: `LibraryDegraded` on the robot's
CoralInstance, the tree's Fallback instead of a wait on the dead skillset, and the way back.

The container is killed through the CRI (`crictl stop --timeout 0` against the robot's
containerd), as an operator of the node would do it. The kubelet restarts it (restartPolicy
Always), the skillset exports its plugin again, and the executor, still running, calls it again:
the library recovers and `LibraryDegraded` turns False.

The mission's inspection waits on the example skillset's count topic (a long wait, so the kill
lands while the behavior is RUNNING); the Fallback reports instead, then the mission counts again
until the restarted skillset answers.
"""

from __future__ import annotations

from coral_testbed.cluster import Cluster, realrobots
from coral_testbed.waiting import wait_for
from fixtures.operator import HelmOperator
from kubernetes import client as k8s

from . import realsystems as rs
from .conftest import first_real_robot, real_robot_marks

pytestmark = real_robot_marks(timeout_s=420)

SYSTEM = "inspection"
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
    cluster: Cluster,
    namespace: str,
    helm_operator: HelmOperator,
    real_robots: realrobots.RealRobots,
    ros_env: dict[str, str],
) -> None:
    robot = first_real_robot(real_robots)
    core = k8s.CoreV1Api(cluster.api_client)
    custom = k8s.CustomObjectsApi(cluster.api_client)
    rs.create(custom, namespace, rs.system(SYSTEM, robot, int(ros_env["ROS_DOMAIN_ID"]), TREE))

    def current() -> dict:
        return rs.instance(custom, namespace, SYSTEM)

    def waiting_on_skillset() -> bool:
        tree = rs.tree(current())
        return tree.get("rootStatus") == "RUNNING" and "WaitForCount" in tree.get("activePath", "")

    wait_for(
        waiting_on_skillset,
        timeout=240,
        message=lambda: f"tree RUNNING in WaitForCount: {current()}\n{helm_operator.logs()[-2000:]}",
    )
    (pod,) = rs.pods(core, namespace, SYSTEM, rs.SKILLSET)
    killed = rs.container_id(pod.status.container_statuses[0])
    # What an operator of the node sees: the running container, found by its kubelet labels.
    listed = real_robots.cri(
        robot, "ps", "-q",
        "--label", f"io.kubernetes.pod.namespace={namespace}",
        "--label", f"io.kubernetes.container.name={rs.SKILLSET}",
    ).stdout.split()  # fmt: skip
    assert listed == [killed]
    real_robots.cri(robot, "stop", "--timeout", "0", killed)

    def logs() -> str:
        executor = rs.pods(core, namespace, SYSTEM, "executor")
        name = executor[0].metadata.name if executor else "-"
        result = cluster.kubectl("logs", "-n", namespace, name, check=False)
        return f"{current()}\n--- executor:\n{(result.stdout + result.stderr)[-3000:]}"

    def fell_back() -> dict:
        item = current()
        failure = rs.tree(item).get("lastFailure") or {}
        return item if "WaitForCount" in failure.get("path", "") else {}

    # The dead skillset's behavior fails at once instead of waiting out its 180 s.
    item = wait_for(fell_back, timeout=60, interval=0.3, message=lambda: f"the Fallback: {logs()}")
    failure = rs.tree(item)["lastFailure"]
    assert rs.SKILLSET in failure["message"], failure
    assert rs.tree(item)["rootStatus"] == "RUNNING", rs.tree(item)

    degraded = wait_for(
        lambda: (c := rs.condition(current(), "LibraryDegraded")).get("status") == "True" and c,
        timeout=60,
        interval=0.3,
        message=lambda: f"LibraryDegraded=True: {logs()}",
    )
    assert rs.SKILLSET in degraded["message"], degraded

    # The kubelet restarts the container; the restarted skillset exports its plugin and answers.
    finished = wait_for(
        lambda: rs.with_root(custom, namespace, SYSTEM, "SUCCESS", "FAILURE"),
        timeout=180,
        message=lambda: f"the tree to end: {logs()}",
    )
    assert rs.tree(finished)["rootStatus"] == "SUCCESS", rs.tree(finished)
    recovered = wait_for(
        lambda: (c := rs.condition(current(), "LibraryDegraded")).get("status") == "False" and c,
        timeout=60,
        message=lambda: f"LibraryDegraded=False: {current()}",
    )
    assert recovered["reason"] == "LibrariesHealthy", recovered
    (after,) = rs.pods(core, namespace, SYSTEM, rs.SKILLSET)
    status = after.status.container_statuses[0]
    assert after.metadata.uid == pod.metadata.uid, "the pod was replaced instead of its container restarted"
    assert status.restart_count >= 1 and rs.container_id(status) != killed, status
    assert status.last_state.terminated is not None and status.last_state.terminated.exit_code == 137
    rs.delete(custom, namespace, SYSTEM)
