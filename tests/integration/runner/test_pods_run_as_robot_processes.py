"""A pod bound to a runner-managed robot really runs, and its exit is what Kubernetes reports."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest
from coral_testbed.cluster import Cluster
from coral_testbed.waiting import wait_for
from kubernetes import client as k8s

from .conftest import StartRunner
from .podmanifests import is_ready, python_pod, read_pod, wait_phase

pytestmark = [pytest.mark.cluster, pytest.mark.slow]


def test_pod_writes_into_its_robots_host_path_and_succeeds(
    cluster: Cluster, namespace: str, start_runner: StartRunner, robot_names
) -> None:
    r1, r2 = robot_names("r1", "r2")
    runner = start_runner([r1, r2])
    core = k8s.CoreV1Api(cluster.api_client)
    code = "import os; open('/data/out.txt', 'w').write('written by ' + os.environ['HOSTNAME'])"
    core.create_namespaced_pod(namespace, python_pod("writer", r1, code))

    pod = wait_phase(core, "writer", namespace, ("Succeeded", "Failed"))
    assert pod.status.phase == "Succeeded"
    state = pod.status.container_statuses[0].state.terminated
    assert state.exit_code == 0 and state.reason == "Completed"
    assert not is_ready(pod)
    written = runner.host_path(r1, "/srv/data/out.txt")
    assert written.read_text() == "written by writer"
    assert not runner.host_path(r2, "/srv/data/out.txt").exists(), "r2's folder must not see r1's file"
    assert pod.status.host_ip == runner.address(r1)


def test_failing_container_makes_the_pod_failed_with_its_exit_code(
    cluster: Cluster, namespace: str, start_runner: StartRunner, robot_names
) -> None:
    (r1,) = robot_names("r1")
    start_runner([r1])
    core = k8s.CoreV1Api(cluster.api_client)
    core.create_namespaced_pod(namespace, python_pod("failing", r1, "import sys; sys.exit(3)"))

    pod = wait_phase(core, "failing", namespace, ("Succeeded", "Failed"))
    assert pod.status.phase == "Failed"
    terminated = pod.status.container_statuses[0].state.terminated
    assert terminated.exit_code == 3 and terminated.reason == "Error"


def test_on_failure_pod_is_restarted_until_it_succeeds(
    cluster: Cluster, namespace: str, start_runner: StartRunner, robot_names
) -> None:
    (r1,) = robot_names("r1")
    runner = start_runner([r1])
    core = k8s.CoreV1Api(cluster.api_client)
    code = (
        "import os, sys\n"
        "n = len(os.listdir('/data'))\n"
        "open(f'/data/attempt-{n}', 'w').close()\n"
        "sys.exit(0 if n >= 1 else 4)\n"
    )
    core.create_namespaced_pod(
        namespace, python_pod("flaky", r1, code, restart="OnFailure", host_path="/srv/flaky")
    )

    pod = wait_phase(core, "flaky", namespace, ("Succeeded", "Failed"))
    assert pod.status.phase == "Succeeded"
    status = pod.status.container_statuses[0]
    assert status.restart_count == 1
    assert status.last_state.terminated.exit_code == 4
    assert sorted(p.name for p in runner.host_path(r1, "/srv/flaky").iterdir()) == ["attempt-0", "attempt-1"]


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return not Path(f"/proc/{pid}/stat").read_text().split()[2] == "Z"


def test_deleting_a_long_running_pod_stops_its_process(
    cluster: Cluster, namespace: str, start_runner: StartRunner, robot_names
) -> None:
    (r1,) = robot_names("r1")
    runner = start_runner([r1])
    core = k8s.CoreV1Api(cluster.api_client)
    code = "import os, time\nopen('/data/pid', 'w').write(str(os.getpid()))\nwhile True: time.sleep(0.2)\n"
    core.create_namespaced_pod(namespace, python_pod("forever", r1, code, restart="Always"))

    pod = wait_phase(core, "forever", namespace, ("Running",))
    pid_file = runner.host_path(r1, "/srv/data/pid")
    pid = int(wait_for(lambda: pid_file.exists() and pid_file.read_text(), timeout=30, message="pid file"))
    assert _alive(pid)
    wait_for(lambda: is_ready(core.read_namespaced_pod("forever", namespace)), timeout=30, message="Ready")
    assert pod.status.container_statuses[0].container_id.endswith(str(pid))

    core.delete_namespaced_pod("forever", namespace)
    wait_for(lambda: not _alive(pid), timeout=30, message=f"process {pid} of deleted pod to exit")
    wait_for(lambda: read_pod(core, "forever", namespace) is None, timeout=30, message="pod object removed")


def test_env_from_configmap_and_downward_api_reach_the_process(
    cluster: Cluster, namespace: str, start_runner: StartRunner, robot_names
) -> None:
    (r1,) = robot_names("r1")
    runner = start_runner([r1])
    core = k8s.CoreV1Api(cluster.api_client)
    core.create_namespaced_config_map(
        namespace,
        {"metadata": {"name": "settings"}, "data": {"speed": "0.5", "mode": "survey", "tree": "<root/>"}},
    )
    env = [
        {"name": "SPEED", "valueFrom": {"configMapKeyRef": {"name": "settings", "key": "speed"}}},
        {"name": "POD_NAME", "valueFrom": {"fieldRef": {"fieldPath": "metadata.name"}}},
        {"name": "NODE_NAME", "valueFrom": {"fieldRef": {"fieldPath": "spec.nodeName"}}},
        {"name": "GREETING", "value": "hello $(NODE_NAME)"},
        {"name": "TREE_FILE", "value": "/config/tree"},
    ]
    extra = {
        "envFrom": [{"prefix": "CFG_", "configMapRef": {"name": "settings"}}],
        "volumeMounts": [
            {"name": "data", "mountPath": "/data"},
            {"name": "config", "mountPath": "/config", "readOnly": True},
        ],
    }
    code = (
        "import json, os\n"
        "keys = ['SPEED', 'POD_NAME', 'NODE_NAME', 'GREETING', 'CFG_mode']\n"
        "out = {k: os.environ.get(k) for k in keys}\n"
        "out['tree'] = open(os.environ['TREE_FILE']).read()\n"
        "json.dump(out, open('/data/env.json', 'w'))\n"
    )
    manifest = python_pod("envdump", r1, code, env=env, extra=extra)
    manifest["spec"]["volumes"].append({"name": "config", "configMap": {"name": "settings"}})
    core.create_namespaced_pod(namespace, manifest)

    pod = wait_phase(core, "envdump", namespace, ("Succeeded", "Failed"))
    assert pod.status.phase == "Succeeded", runner.agents[r1].errors
    seen = json.loads(runner.host_path(r1, "/srv/data/env.json").read_text())
    assert seen == {
        "SPEED": "0.5",
        "POD_NAME": "envdump",
        "NODE_NAME": r1,
        "GREETING": f"hello {r1}",
        "CFG_mode": "survey",
        "tree": "<root/>",
    }


def test_missing_configmap_is_reported_as_a_container_config_error(
    cluster: Cluster, namespace: str, start_runner: StartRunner, robot_names
) -> None:
    (r1,) = robot_names("r1")
    start_runner([r1])
    core = k8s.CoreV1Api(cluster.api_client)
    env = [{"name": "X", "valueFrom": {"configMapKeyRef": {"name": "absent", "key": "x"}}}]
    core.create_namespaced_pod(namespace, python_pod("misconfigured", r1, "pass", env=env))

    def waiting_reason() -> object:
        pod = read_pod(core, "misconfigured", namespace)
        statuses = (pod.status.container_statuses or []) if pod and pod.status else []
        waiting = statuses[0].state.waiting if statuses else None
        return waiting if waiting and waiting.reason == "CreateContainerConfigError" else None

    waiting = wait_for(waiting_reason, timeout=30, message="CreateContainerConfigError")
    assert "absent" in waiting.message
    assert read_pod(core, "misconfigured", namespace).status.phase == "Pending"
