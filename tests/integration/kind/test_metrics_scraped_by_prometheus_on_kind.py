"""A real Prometheus scrapes the operator and an executor on a kind robot (issue 53, acceptance 1
and 2).

The operator is installed by the chart (`kind_operator`), which serves its metrics on the pod's
port `metrics`; Prometheus reaches it through `kubectl port-forward`, as an administrator's laptop
would, and the executor (on the robot's host network, the default: its node container's) at the
robot's own address on the cluster's network. As a mission runs, PromQL sees the operator's
reconciles, the robot counted ready, the executor's tick rate rise and fall again as the tree ends
in SUCCESS; every query of the shipped dashboard returns series. Then the robot's kubelet stops
(`systemctl stop kubelet` in its node): the shipped CoralRobotsUnreachable alert, its `for`
shortened to 15 s and its rules evaluated every second, fires. The kubelet is started again after.
"""

from __future__ import annotations

import subprocess
import time
from collections.abc import Iterator
from typing import Any

import pytest
from coral_testbed.cluster import operatorchart
from coral_testbed.kind import faults
from coral_testbed.kind.missions import KindMissionStack
from coral_testbed.waiting import wait_for
from fixtures.processes import stop_process_group
from fixtures.prometheus import Prometheus, dashboard_queries, free_port
from missions import realsystems as rs

from .fleet import KindCluster, ready

pytestmark = [pytest.mark.slow, pytest.mark.ros, pytest.mark.timeout(900)]

ROBOT = "relay-server"
SYSTEM = "metered"
METRICS_PORT = 19464
OPERATOR_METRICS_PORT = 8081
# Sixty service calls, each a wake-up of the tree: the executor ticks at its rate (10 Hz) for a few
# seconds, then the tree succeeds and the executor ends.
TREE = rs.mission_tree('<Repeat num_cycles="60"><Count count="{count}"/></Repeat>')


@pytest.fixture
def operator_metrics(kind_operator: KindMissionStack) -> Iterator[str]:
    """host:port on 127.0.0.1 forwarded to the operator pod's metrics port; closed at teardown."""
    cluster, release = kind_operator.cluster, kind_operator.release
    (pod,) = operatorchart.operator_pods(cluster.api_client, release)
    assert cluster.bin_dir is not None
    port = free_port()
    forward = subprocess.Popen(
        [
            str(cluster.bin_dir / "kubectl"),
            "port-forward",
            "-n",
            release.namespace,
            f"pod/{pod.metadata.name}",
            f"{port}:{OPERATOR_METRICS_PORT}",
            "--address",
            "127.0.0.1",
        ],
        env=cluster.env(),
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        start_new_session=True,
    )
    try:
        assert forward.stdout is not None
        line = forward.stdout.readline()
        assert "Forwarding from" in line, line
        yield f"127.0.0.1:{port}"
    finally:
        stop_process_group(forward)


def _system(domain: int) -> dict[str, Any]:
    manifest = rs.system(SYSTEM, ROBOT, domain, TREE)
    manifest["spec"]["executors"][0]["metrics"] = {"port": METRICS_PORT}
    return manifest


def test_prometheus_sees_reconciles_robots_and_tick_rate_and_fires_the_unreachable_alert(
    kind_cluster: KindCluster,
    kind_operator: KindMissionStack,
    operator_metrics: str,
    ros_env: dict[str, str],
    prometheus: Prometheus,
) -> None:
    custom, namespace = kind_operator.custom, kind_operator.namespace
    began = time.time()
    executor = f"{faults.robot_address(kind_operator.running, ROBOT)}:{METRICS_PORT}"
    prometheus.start(
        {"coral-operator": [operator_metrics], "coral-executor": [executor]},
        alert_for={"CoralRobotsUnreachable": "15s"},
    )

    def diagnosis() -> str:
        return (
            f"targets: {prometheus.targets()}\ninstance: {rs.instance(custom, namespace, SYSTEM)}\n"
            f"operator:\n{kind_operator.operator_log_tail(2000)}"
        )

    wait_for(
        lambda: (prometheus.value('sum(coral_robots{state="ready"})') or 0) >= 1,
        timeout=60,
        message=lambda: f"the operator's robots in Prometheus: {prometheus.targets()}",
    )
    rs.create(custom, namespace, _system(int(ros_env["ROS_DOMAIN_ID"])))

    # The executor's tick rate rises as the mission runs...
    wait_for(
        lambda: (prometheus.value("sum(rate(coral_executor_ticks_total[3s]))") or 0) > 1,
        timeout=300,
        message=lambda: f"the executor's ticks in Prometheus:\n{diagnosis()}",
    )
    # ...and the operator reports the tree's success, after which the executor ticks no more.
    wait_for(
        lambda: (
            prometheus.value(
                f'sum(coral_instance_trees{{namespace="{namespace}",system="{SYSTEM}",state="SUCCESS"}})'
            )
            == 1
        ),
        timeout=120,
        message=lambda: f"the tree's SUCCESS in the operator's metrics:\n{diagnosis()}",
    )
    wait_for(
        lambda: not prometheus.query("rate(coral_executor_ticks_total[3s]) > 0"),
        timeout=30,
        message=lambda: f"the tick rate to fall once the tree ended:\n{diagnosis()}",
    )
    peak = prometheus.value("max_over_time(rate(coral_executor_ticks_total[3s])[10m:1s])")
    assert peak is not None and peak > 1, peak
    assert prometheus.value('sum(max_over_time(coral_executor_tree_status{status="RUNNING"}[10m]))') == 1
    calls = prometheus.value(
        'max_over_time(coral_executor_behavior_results_total{behavior="Count",result="SUCCESS"}[10m])'
    )
    assert calls is not None and calls >= 50, calls
    reconciles = prometheus.value('sum(coral_operator_reconciles_total{result="success"})')
    assert reconciles is not None and reconciles > 0
    instance_passes = prometheus.value(
        'sum(increase(coral_operator_reconciles_total{kind="CoralInstance",result="success"}[10m]))'
    )
    assert instance_passes is not None and instance_passes > 0, instance_passes
    writes = prometheus.query('resource_verb:coral_operator_api_writes:rate5m{resource="pods",verb="create"}')
    assert writes, prometheus.query("resource_verb:coral_operator_api_writes:rate5m")

    empty = [
        f"{title}: {expr}" for title, expr in dashboard_queries() if not prometheus.query_range(expr, began)
    ]
    assert not empty, "dashboard queries without series:\n" + "\n".join(empty)

    running = kind_cluster.running
    node = faults.node_of(running, ROBOT)
    faults.stop_kubelet(running, ROBOT)
    try:
        wait_for(
            lambda: (prometheus.value('sum(coral_robots{state="unreachable"})') or 0) >= 1,
            timeout=180,
            message=lambda: f"the robot counted unreachable:\n{diagnosis()}",
        )
        unreachable_since = time.monotonic()
        firing = wait_for(
            lambda: [
                a
                for a in prometheus.alerts()
                if a["labels"]["alertname"] == "CoralRobotsUnreachable" and a["state"] == "firing"
            ],
            timeout=60,
            message=lambda: f"CoralRobotsUnreachable to fire: {prometheus.alerts()}",
        )
        # Not before its (shortened) threshold: pending first, firing once it held for 15 s.
        assert time.monotonic() - unreachable_since >= 10, firing
        assert firing[0]["labels"]["severity"] == "warning"
    finally:
        faults.start_kubelet(running, ROBOT)
        # The robot is back for the folder's next test.
        wait_for(
            lambda: ready(kind_operator.core, node) == "True",
            timeout=120,
            interval=1,
            message=f"{node} Ready again",
        )
