"""The runner acts as the robots' kubelet: Node readiness, readiness probes, adoption from kwok, and
clean-up after a runner that was killed."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from coral_testbed.cluster import Cluster
from coral_testbed.runner import network
from coral_testbed.waiting import holds_for, wait_for
from kubernetes import client as k8s
from kubernetes.client.exceptions import ApiException

from .conftest import StartRunner
from .podmanifests import is_ready, python_pod, wait_phase

pytestmark = [pytest.mark.cluster, pytest.mark.slow]

LONG_RUNNING = (
    "import os, time\nopen('/data/pid', 'w').write(str(os.getpid()))\nwhile True: time.sleep(0.2)\n"
)


def _node_ready(core: k8s.CoreV1Api, name: str) -> str | None:
    node = core.read_node(name)
    return next((c.status for c in node.status.conditions or [] if c.type == "Ready"), None)


def test_robot_node_is_ready_while_the_runner_runs_and_not_ready_after_it_stops(
    cluster: Cluster, start_runner: StartRunner, robot_names
) -> None:
    (r1,) = robot_names("r1")
    runner = start_runner([r1])
    core = k8s.CoreV1Api(cluster.api_client)
    node = core.read_node(r1)
    assert node.metadata.labels["coral.dev/robot"] == r1
    assert "kwok.x-k8s.io/node" not in (node.metadata.annotations or {})
    assert _node_ready(core, r1) == "True"
    assert node.status.addresses[0].address == runner.address(r1)

    runner.stop()
    assert _node_ready(core, r1) == "False"
    assert core.read_node(r1).status.conditions[-1].reason == "RobotRunnerStopped"


def test_readiness_probe_decides_the_ready_condition(
    cluster: Cluster, namespace: str, start_runner: StartRunner, robot_names
) -> None:
    (r1,) = robot_names("r1")
    runner = start_runner([r1])
    core = k8s.CoreV1Api(cluster.api_client)
    probe = {"exec": {"command": ["test", "-f", "/data/ready"]}, "periodSeconds": 1, "failureThreshold": 1}
    manifest = python_pod("gated", r1, LONG_RUNNING, restart="Always", extra={"readinessProbe": probe})
    core.create_namespaced_pod(namespace, manifest)
    wait_phase(core, "gated", namespace, ("Running",))

    def ready() -> bool:
        return is_ready(core.read_namespaced_pod("gated", namespace))

    holds_for(lambda: not ready(), duration=3.0, message="pod not Ready before its marker exists")
    marker = runner.host_path(r1, "/srv/data/ready")
    marker.write_text("")
    wait_for(ready, timeout=20, message="pod Ready once the probe passes")
    marker.unlink()
    wait_for(lambda: not ready(), timeout=20, message="pod not Ready once the probe fails")


def test_adopting_a_kwok_robot_keeps_its_pods_and_runs_them(
    cluster: Cluster, namespace: str, start_runner: StartRunner, robot_names
) -> None:
    (r1,) = robot_names("r1")
    cluster.add_robots([r1], {"coral.dev/model": "test-bot"})
    core = k8s.CoreV1Api(cluster.api_client)
    core.create_namespaced_pod(namespace, python_pod("early", r1, "print('hi')"))
    wait_phase(core, "early", namespace, ("Running",))  # kwok pretends it runs

    with pytest.raises(Exception, match="simulated by kwok"):
        start_runner([r1])
    runner = start_runner([r1], adopt=True)

    pod = wait_phase(core, "early", namespace, ("Succeeded", "Failed"))
    assert pod.status.phase == "Succeeded"
    node = core.read_node(r1)
    assert node.metadata.labels["coral.dev/model"] == "test-bot"
    assert "kwok.x-k8s.io/node" not in (node.metadata.annotations or {})
    log = runner.robot_dir(r1) / "pods" / f"{namespace}_early" / "logs" / "main.log"
    assert log.read_text() == "hi\n"

    # kwok has let go: a new pod's fate is the process's, and nobody rewrites it afterwards.
    core.create_namespaced_pod(namespace, python_pod("late", r1, "import sys; sys.exit(5)"))
    pod = wait_phase(core, "late", namespace, ("Succeeded", "Failed"))
    assert pod.status.phase == "Failed", pod.status
    assert pod.status.pod_ip == runner.address(r1)
    holds_for(
        lambda: core.read_namespaced_pod("late", namespace).status.phase == "Failed",
        duration=3.0,
        message="late pod stays Failed",
    )


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return Path(f"/proc/{pid}/stat").read_text().split()[2] != "Z"


def test_leftovers_of_a_killed_runner_are_removed_by_the_next_one(
    cluster: Cluster, namespace: str, robot_names, tmp_path: Path
) -> None:
    (r1,) = robot_names("r1")
    core = k8s.CoreV1Api(cluster.api_client)
    log = tmp_path / "runner.log"
    with log.open("w") as out:
        runner = subprocess.Popen(
            [sys.executable, "-m", "coral", "robot-runner", r1, "--root", str(tmp_path / "robots")],
            env=cluster.env(),
            stdout=out,
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )
    try:
        wait_for(lambda: "Robot runner ready" in log.read_text(), timeout=60, message=lambda: log.read_text())
        core.create_namespaced_pod(namespace, python_pod("orphan", r1, LONG_RUNNING, restart="Always"))
        pid_file = tmp_path / "robots" / r1 / "host" / "srv" / "data" / "pid"
        pid = int(wait_for(lambda: pid_file.exists() and pid_file.read_text(), timeout=60, message="pid"))
        os.kill(runner.pid, signal.SIGKILL)
        runner.wait(timeout=10)
        assert _alive(pid), "the pod process outlives its killed runner (as a crash would leave it)"

        freed = network.cleanup_stale()

        assert freed, "cleanup found nothing of the killed runner"
        wait_for(lambda: not _alive(pid), timeout=10, message=f"leftover process {pid} to be killed")
        for slot in freed:
            assert not network.slot_resources(slot)
    finally:
        if runner.poll() is None:
            os.killpg(runner.pid, signal.SIGKILL)
            runner.wait(timeout=10)
        network.cleanup_stale()
        try:
            core.delete_node(r1)
        except ApiException as error:
            if error.status != 404:
                raise


def _lease_renewed(coordination: k8s.CoordinationV1Api, name: str) -> object:
    return coordination.read_namespaced_lease(name, "kube-node-lease").spec.renew_time


def test_command_cuts_links_on_annotation_and_stops_cleanly_on_sigterm(
    cluster: Cluster, robot_names, tmp_path: Path
) -> None:
    (r1,) = robot_names("r1")
    core = k8s.CoreV1Api(cluster.api_client)
    log = tmp_path / "runner.log"
    with log.open("w") as out:
        runner = subprocess.Popen(
            [sys.executable, "-m", "coral", "robot-runner", r1, "-v", "--root", str(tmp_path / "robots")],
            env=cluster.env(),
            stdout=out,
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )
    try:
        wait_for(lambda: "Robot runner ready" in log.read_text(), timeout=60, message=lambda: log.read_text())
        assert _node_ready(core, r1) == "True"

        coordination = k8s.CoordinationV1Api(cluster.api_client)
        core.patch_node(r1, {"metadata": {"annotations": {"coral.dev/simulate-link": "down"}}})
        wait_for(
            lambda: f"Robot {r1} link cut" in log.read_text(), timeout=30, message=lambda: log.read_text()
        )
        frozen = _lease_renewed(coordination, r1)
        holds_for(lambda: _lease_renewed(coordination, r1) == frozen, duration=12.0, message="lease frozen")
        core.patch_node(r1, {"metadata": {"annotations": {"coral.dev/simulate-link": "up"}}})
        wait_for(
            lambda: _lease_renewed(coordination, r1) != frozen, timeout=30, message="lease renewed again"
        )

        runner.send_signal(signal.SIGTERM)
        assert runner.wait(timeout=60) == 0, log.read_text()
        assert "Robot runner stopped" in log.read_text()
        assert _node_ready(core, r1) == "False"
        assert not [
            line
            for line in subprocess.run(
                ["ip", "netns", "list"], capture_output=True, text=True, check=False
            ).stdout.splitlines()
            if line.split(" ")[0].endswith(f"-{r1}")
        ]
    finally:
        if runner.poll() is None:
            os.killpg(runner.pid, signal.SIGKILL)
            runner.wait(timeout=10)
        core.delete_node(r1)
