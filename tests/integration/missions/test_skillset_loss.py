"""Acceptance 3: a skillset process killed on a robot mid-mission shows `LibraryDegraded` on that
robot's CoralInstance, and the tree takes its Fallback instead of waiting on the dead skillset.

The mission's inspection waits on the examples skillset's count topic (a long wait, so the kill
lands while the behavior is RUNNING); the Fallback reports instead.
"""

from __future__ import annotations

import os
import signal

import pytest
from coral_testbed.cluster import Cluster
from coral_testbed.missions import following
from coral_testbed.waiting import wait_for
from kubernetes import client as k8s

from .conftest import StartStack, wait_finished

pytestmark = [pytest.mark.cluster, pytest.mark.slow, pytest.mark.ros, pytest.mark.timeout(300)]

TREE = """<root BTCPP_format="4" main_tree_to_execute="Main">
  <BehaviorTree ID="Main">
    <Fallback>
      <Sequence name="Inspect">
        <Count count="{count}"/>
        <WaitForCount threshold="1000" timeout_ms="120000"/>
      </Sequence>
      <Greet name="ReportLostSkillset" who="inspection abandoned" greeting="{report}"/>
    </Fallback>
  </BehaviorTree>
</root>
"""


def _system(robot: str, domain: int) -> str:
    return f"""apiVersion: coral.dev/v1alpha1
kind: CoralSystem
metadata:
  name: inspection
spec:
  robots:
    matchLabels:
      coral.dev/robot: {robot}
  ros:
    domainId: {domain}
  parameters:
    inline: |
      examples:
        ros__parameters: {{}}
  tree:
    tickRateHz: 10.0
    inline: |
{"".join("      " + line + chr(10) for line in TREE.splitlines())}  skillsets:
  - name: examples
    image: coral/example-skillset:0.1.0
    args: ["--params", "/etc/coral/params.yaml"]
  executors:
  - name: executor
    image: coral/executor:0.1.0
"""


def test_killed_skillset_degrades_the_instance_and_the_tree_falls_back(
    cluster: Cluster,
    namespace: str,
    start_stack: StartStack,
    suffix: str,
    ros_env: dict[str, str],
) -> None:
    robot = f"m-kill-{suffix}"
    stack = start_stack([robot])
    cluster.kubectl("apply", "-n", namespace, "-f", "-", input=_system(robot, int(ros_env["ROS_DOMAIN_ID"])))

    def waiting_on_skillset() -> bool:
        tree = following.tree(stack.instance_of(robot) or {})
        return tree.get("rootStatus") == "RUNNING" and "WaitForCount" in tree.get("activePath", "")

    wait_for(
        waiting_on_skillset,
        timeout=180,
        message=lambda: (
            f"tree RUNNING in WaitForCount: {stack.instance_of(robot)}\n{stack.operator_log_tail()}"
        ),
    )
    core = k8s.CoreV1Api(cluster.api_client)
    pod = core.list_namespaced_pod(namespace, label_selector="coral.dev/component=examples").items[0]
    pid = int(pod.status.container_statuses[0].container_id.rsplit("/", 1)[-1])
    os.kill(pid, signal.SIGKILL)

    instance = wait_finished(stack, [robot], timeout=90)[robot]
    tree = following.tree(instance)
    assert tree["rootStatus"] == "SUCCESS", tree
    failure = tree.get("lastFailure") or {}
    assert "WaitForCount" in failure.get("path", "") and "examples" in failure.get("message", ""), failure

    def degraded() -> dict:
        return following.condition(stack.instance_of(robot) or {}, "LibraryDegraded")

    condition = wait_for(
        lambda: degraded().get("status") == "True" and degraded(),
        timeout=60,
        message=lambda: f"LibraryDegraded=True: {stack.instance_of(robot)}",
    )
    assert "examples" in condition["message"], condition
    # The runner restarts the killed skillset (restartPolicy Always), as a kubelet would.
    wait_for(
        lambda: (
            core.read_namespaced_pod(pod.metadata.name, namespace).status.container_statuses[0].restart_count
            >= 1
        ),
        timeout=60,
        message="the killed skillset restarted",
    )
