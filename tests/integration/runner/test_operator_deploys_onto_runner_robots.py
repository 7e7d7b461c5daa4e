"""End to end with the Coral operator: a CoralSystem applied to a runner-managed robot gets its
skillset really started and gated Ready on the exported plugin marker, only then its executor, whose
tree and plugins are real files on the robot, and the executor's tree status, written through the
API from inside the robot's network namespace with its own ServiceAccount, reaches the CoralInstance.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from coral_testbed.cluster import Cluster
from coral_testbed.waiting import wait_for
from fixtures.operator import opened_policy
from fixtures.processes import Spawn
from kubernetes import client as k8s

from .conftest import StartRunner
from .podmanifests import is_ready, read_pod

pytestmark = [pytest.mark.cluster, pytest.mark.slow, pytest.mark.ros]

ROOT = Path(__file__).resolve().parents[3]
TREE = """<root BTCPP_format="4" main_tree_to_execute="Main">
  <BehaviorTree ID="Main">
    <Greet who="robot" greeting="{greeting}"/>
  </BehaviorTree>
</root>
"""


def _system(robot: str, domain: int) -> dict[str, Any]:
    return {
        "apiVersion": "coral.dev/v1alpha1",
        "kind": "CoralSystem",
        "metadata": {"name": "hello"},
        "spec": {
            "robots": {"matchLabels": {"coral.dev/robot": robot}},
            "ros": {"domainId": domain},
            "parameters": {"inline": "examples:\n  ros__parameters: {}\n"},
            "tree": {"inline": TREE, "tickRateHz": 10.0},
            "skillsets": [
                {
                    "name": "examples",
                    "image": "coral/examples-skillset:0.1.0",
                    "command": [
                        "python",
                        "-m",
                        "coral_skillsets.examples",
                        "--plugins",
                        "$(CORAL_PLUGIN_DIR)",
                    ],
                }
            ],
            "executors": [{"name": "executor", "image": "coral/executor:0.1.0"}],
        },
    }


def _pod_named(core: k8s.CoreV1Api, namespace: str, component: str) -> k8s.V1Pod | None:
    pods = core.list_namespaced_pod(namespace, label_selector=f"coral.dev/component={component}").items
    return pods[0] if pods else None


def test_coral_system_runs_skillset_then_executor_on_a_runner_robot(
    cluster: Cluster,
    namespace: str,
    start_runner: StartRunner,
    robot_names,
    spawned: Spawn,
    ros_env: dict[str, str],
    tmp_path: Path,
) -> None:
    cluster.kubectl("apply", "--server-side", "--force-conflicts", "-f", str(ROOT / "crds"))
    established = 'jsonpath={.status.conditions[?(@.type=="Established")].status}'
    for crd in ("coralsystems.coral.dev", "coralinstances.coral.dev"):
        # `kubectl wait` fails outright while a new CRD has no status yet; poll instead.
        wait_for(
            lambda crd=crd: (
                cluster.kubectl("get", "crd", crd, "-o", established, check=False).stdout == "True"
            ),
            timeout=60,
            message=f"CRD {crd} Established",
        )
    (r1,) = robot_names("r1")
    runner = start_runner([r1])
    with (tmp_path / "operator.log").open("w") as log:
        operator = spawned(
            [sys.executable, "-m", "coral_operator", "-n", namespace],
            env={**cluster.env(), **opened_policy(namespace), "PYTHONUNBUFFERED": "1"},
            stdout=log,
            stderr=subprocess.STDOUT,
        )
    core = k8s.CoreV1Api(cluster.api_client)
    custom = k8s.CustomObjectsApi(cluster.api_client)
    custom.create_namespaced_custom_object(
        "coral.dev", "v1alpha1", namespace, "coralsystems", _system(r1, int(ros_env["ROS_DOMAIN_ID"]))
    )

    def operator_log() -> str:
        return (tmp_path / "operator.log").read_text()[-3000:]

    def skillset_ready() -> k8s.V1Pod | None:
        assert operator.poll() is None, f"the operator exited:\n{operator_log()}"
        pod = _pod_named(core, namespace, "examples")
        return pod if pod is not None and is_ready(pod) else None

    skillset = wait_for(
        skillset_ready,
        timeout=120,
        message=lambda: f"skillset pod Ready; operator log:\n{operator_log()}",
    )
    plugins = runner.host_path(r1, f"/var/lib/coral/plugins/{namespace}/hello")
    assert (plugins / "examples" / "ready").exists(), sorted(p.name for p in plugins.iterdir())
    assert skillset.status.host_ip == runner.address(r1)

    def executor_started() -> k8s.V1Pod | None:
        pod = _pod_named(core, namespace, "executor")
        statuses = (pod.status.container_statuses or []) if pod and pod.status else []
        if statuses and (
            statuses[0].state.running or statuses[0].state.terminated or statuses[0].last_state.terminated
        ):
            return pod
        return None

    executor = wait_for(executor_started, timeout=120, message=lambda: f"executor started:\n{operator_log()}")
    ready_since = next(c.last_transition_time for c in skillset.status.conditions if c.type == "Ready")
    assert executor.metadata.creation_timestamp >= ready_since, (
        "executor created before its skillset was Ready"
    )
    tree_files = list(
        (runner.robot_dir(r1) / "pods" / f"{namespace}_{executor.metadata.name}").rglob("tree.xml")
    )
    assert tree_files and tree_files[0].read_text() == TREE
    assert read_pod(core, skillset.metadata.name, namespace) is not None

    # The executor, run by the runner inside the robot's namespace, reports through the API.
    def tree_status() -> dict[str, Any]:
        items = custom.list_namespaced_custom_object("coral.dev", "v1alpha1", namespace, "coralinstances")[
            "items"
        ]
        return ((items[0].get("status") or {}).get("tree") or {}) if items else {}

    executor_log = (
        runner.robot_dir(r1) / "pods" / f"{namespace}_{executor.metadata.name}" / "logs" / "executor.log"
    )
    wait_for(
        lambda: tree_status().get("rootStatus") == "SUCCESS",
        timeout=120,
        message=lambda: (
            f"tree SUCCESS on the CoralInstance (now {tree_status()}); executor log:\n"
            + executor_log.read_text()[-2000:]
        ),
    )
