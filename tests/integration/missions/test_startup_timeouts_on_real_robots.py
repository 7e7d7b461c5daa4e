"""The startup gate's health timeout (`spec.startup`) with real readiness probes on a real robot.

The example skillset runs and exports its plugin, but its readiness probe (run by the robot's
kubelet in the container) checks a file that is not there, so the skillset stage never becomes
ready. With `onTimeout: Block` the executor is held: once the timeout passes, `ComponentsReady`
says `HealthTimeout` ("later stages blocked") and the instance is `Stalled`, as docs/verdicts.md
says; when the probe passes at last, the executor starts. With `onTimeout: Proceed` the executor
starts when the timeout falls due, not before, and the mission runs; `ComponentsReady` still says
`HealthTimeout` ("later stages started anyway") but the instance is not Stalled.
"""

from __future__ import annotations

from datetime import timedelta

from coral_testbed.cluster import Cluster, realrobots
from coral_testbed.waiting import holds_for, wait_for
from fixtures.operator import HelmOperator
from kubernetes import client as k8s

from . import realsystems as rs
from .conftest import first_real_robot, real_robot_marks

pytestmark = real_robot_marks(timeout_s=420)

TIMEOUT_S = 20
PROBED_FILE = "/tmp/probe-passes"
# One probe period of the kubelet; the probe fails on the first miss.
READINESS = {"exec": ["test", "-f", PROBED_FILE], "periodSeconds": 1, "failureThreshold": 1}
TREE = """<root BTCPP_format="4" main_tree_to_execute="Main">
  <BehaviorTree ID="Main">
    <Count count="{count}"/>
  </BehaviorTree>
</root>
"""


def _start(
    cluster: Cluster, namespace: str, robot: str, domain: int, name: str, on_timeout: str
) -> tuple[k8s.CoreV1Api, k8s.CustomObjectsApi]:
    custom = k8s.CustomObjectsApi(cluster.api_client)
    startup = {"healthTimeoutSeconds": TIMEOUT_S, "onTimeout": on_timeout}
    rs.create(custom, namespace, rs.system(name, robot, domain, TREE, startup=startup, readiness=READINESS))
    return k8s.CoreV1Api(cluster.api_client), custom


def _timed_out(custom: k8s.CustomObjectsApi, namespace: str, name: str) -> dict:
    item = rs.instance(custom, namespace, name)
    return item if rs.condition(item, "ComponentsReady").get("reason") == "HealthTimeout" else {}


def _running_unready(core: k8s.CoreV1Api, namespace: str, name: str) -> bool:
    pods = rs.pods(core, namespace, name, rs.SKILLSET)
    statuses = pods[0].status.container_statuses or [] if pods else []
    return bool(statuses) and statuses[0].state.running is not None and not statuses[0].ready


def test_block_holds_the_executor_while_a_real_probe_fails(
    cluster: Cluster,
    namespace: str,
    helm_operator: HelmOperator,
    real_robots: realrobots.RealRobots,
    ros_env: dict[str, str],
) -> None:
    name = "held"
    robot = first_real_robot(real_robots)
    core, custom = _start(cluster, namespace, robot, int(ros_env["ROS_DOMAIN_ID"]), name, "Block")
    wait_for(
        lambda: _running_unready(core, namespace, name),
        timeout=180,
        message=lambda: f"the skillset running, not ready: {rs.pods(core, namespace, name)}",
    )
    item = wait_for(
        lambda: _timed_out(custom, namespace, name),
        timeout=TIMEOUT_S + 60,
        message=lambda: f"ComponentsReady=HealthTimeout: {rs.instance(custom, namespace, name)}",
    )
    components = rs.condition(item, "ComponentsReady")
    assert components["status"] == "False", components
    assert (
        "examples" in components["message"]
        and "later stages blocked (onTimeout=Block)" in components["message"]
    ), components
    stalled = rs.condition(item, "Stalled")
    assert (stalled["status"], stalled["reason"]) == ("True", "HealthTimeout"), stalled
    holds_for(
        lambda: not rs.pods(core, namespace, name, "executor"),
        duration=10,
        interval=1,
        message="no executor pod while the skillset's probe fails",
    )

    # The probe passes (the kubelet sees the file in the container): the gate opens.
    (pod,) = rs.pods(core, namespace, name, rs.SKILLSET)
    cluster.kubectl("exec", "-n", namespace, pod.metadata.name, "-c", rs.SKILLSET, "--", "touch", PROBED_FILE)
    finished = wait_for(
        lambda: rs.with_root(custom, namespace, name, "SUCCESS"),
        timeout=180,
        message=lambda: f"the released mission to succeed: {rs.instance(custom, namespace, name)}",
    )
    assert rs.condition(finished, "Stalled")["status"] == "False", rs.condition(finished, "Stalled")
    rs.delete(custom, namespace, name)


def test_proceed_starts_the_executor_when_the_timeout_falls_due(
    cluster: Cluster,
    namespace: str,
    helm_operator: HelmOperator,
    real_robots: realrobots.RealRobots,
    ros_env: dict[str, str],
) -> None:
    name = "proceeding"
    robot = first_real_robot(real_robots)
    core, custom = _start(cluster, namespace, robot, int(ros_env["ROS_DOMAIN_ID"]), name, "Proceed")
    finished = wait_for(
        lambda: rs.with_root(custom, namespace, name, "SUCCESS"),
        timeout=240,
        message=lambda: f"the mission to succeed: {rs.instance(custom, namespace, name)}",
    )
    (skillset,) = rs.pods(core, namespace, name, rs.SKILLSET)
    (executor,) = rs.pods(core, namespace, name, "executor")
    # The probe never passed, and the executor waited the whole timeout for it.
    assert not skillset.status.container_statuses[0].ready
    assert executor.metadata.creation_timestamp >= skillset.metadata.creation_timestamp + timedelta(
        seconds=TIMEOUT_S
    ), (skillset.metadata.creation_timestamp, executor.metadata.creation_timestamp)
    components = rs.condition(finished, "ComponentsReady")
    assert (components["status"], components["reason"]) == ("False", "HealthTimeout"), components
    assert "later stages started anyway (onTimeout=Proceed)" in components["message"], components
    assert rs.condition(finished, "Stalled")["status"] == "False", rs.condition(finished, "Stalled")
    rs.delete(custom, namespace, name)
