"""The startup gate's health timeout (`spec.startup`) with real readiness probes on a kind robot.

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

import pytest
from coral_testbed.kind.missions import KindMissionStack
from coral_testbed.waiting import holds_for, wait_for
from missions import realsystems as rs

from .fleet import Mission

pytestmark = [pytest.mark.slow, pytest.mark.ros, pytest.mark.timeout(1800)]

ROBOT = "relay-survey"
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


def _start(kind_operator: KindMissionStack, domain: int, name: str, on_timeout: str) -> Mission:
    startup = {"healthTimeoutSeconds": TIMEOUT_S, "onTimeout": on_timeout}
    return Mission(kind_operator, ROBOT, name, domain, TREE, startup=startup, readiness=READINESS)


def _timed_out(mission: Mission) -> dict:
    item = mission.instance()
    return item if rs.condition(item, "ComponentsReady").get("reason") == "HealthTimeout" else {}


def _running_unready(mission: Mission) -> bool:
    pod = mission.pods(rs.SKILLSET).get(rs.SKILLSET)
    statuses = pod.status.container_statuses or [] if pod else []
    return bool(statuses) and statuses[0].state.running is not None and not statuses[0].ready


def test_block_holds_the_executor_while_a_real_probe_fails(
    kind_operator: KindMissionStack, ros_env: dict[str, str]
) -> None:
    mission = _start(kind_operator, int(ros_env["ROS_DOMAIN_ID"]), "held", "Block")
    wait_for(
        lambda: _running_unready(mission),
        timeout=180,
        message=lambda: f"the skillset running, not ready: {mission.pods()}",
    )
    item = wait_for(
        lambda: _timed_out(mission),
        timeout=TIMEOUT_S + 60,
        message=lambda: f"ComponentsReady=HealthTimeout: {mission.instance()}",
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
        lambda: not mission.pods("executor"),
        duration=10,
        interval=1,
        message="no executor pod while the skillset's probe fails",
    )

    # The probe passes (the kubelet sees the file in the container): the gate opens.
    pod = mission.pods(rs.SKILLSET)[rs.SKILLSET]
    kind_operator.cluster.kubectl(
        "exec",
        "-n",
        kind_operator.namespace,
        pod.metadata.name,
        "-c",
        rs.SKILLSET,
        "--",
        "touch",
        PROBED_FILE,
    )
    finished = wait_for(
        lambda: mission.with_root("SUCCESS"),
        timeout=180,
        message=lambda: f"the released mission to succeed: {mission.instance()}\n{mission.logs()}",
    )
    assert rs.condition(finished, "Stalled")["status"] == "False", rs.condition(finished, "Stalled")


def test_proceed_starts_the_executor_when_the_timeout_falls_due(
    kind_operator: KindMissionStack, ros_env: dict[str, str]
) -> None:
    mission = _start(kind_operator, int(ros_env["ROS_DOMAIN_ID"]), "proceeding", "Proceed")
    finished = wait_for(
        lambda: mission.with_root("SUCCESS"),
        timeout=240,
        message=lambda: f"the mission to succeed: {mission.instance()}\n{mission.logs()}",
    )
    pods = mission.pods()
    skillset, executor = pods[rs.SKILLSET], pods["executor"]
    # The probe never passed, and the executor waited the whole timeout for it.
    assert not skillset.status.container_statuses[0].ready
    assert executor.metadata.creation_timestamp >= skillset.metadata.creation_timestamp + timedelta(
        seconds=TIMEOUT_S
    ), (skillset.metadata.creation_timestamp, executor.metadata.creation_timestamp)
    components = rs.condition(finished, "ComponentsReady")
    assert (components["status"], components["reason"]) == ("False", "HealthTimeout"), components
    assert "later stages started anyway (onTimeout=Proceed)" in components["message"], components
    assert rs.condition(finished, "Stalled")["status"] == "False", rs.condition(finished, "Stalled")
