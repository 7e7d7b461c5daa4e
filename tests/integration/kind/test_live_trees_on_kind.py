"""A robot's live tree from outside the cluster (issue 49, acceptance 3): `coral tree watch SYSTEM
ROBOT --once --json` and `coral groot2 SYSTEM ROBOT` reach the executor's Groot2 publisher on a
kind robot through the API server's port-forward, as a user on a laptop would.

Where the operator's policy opens Groot2 hooks for the namespace, a breakpoint set before the
mission starts (the executor holds its first tick for the debugger) is reached and forces a
failing safety check to SUCCESS: the robot's CoralInstance records no failure. Where it does not,
a system asking for hooks is refused whole (`Stalled`/`PolicyDenied`, naming the field); without
them the hook request gets the error reply and the tree runs on untouched, its check's failure
recorded. The operator is the chart's (`kind_operator`), upgraded by Helm with the chart's
`policy.groot2HooksNamespaces` for the test that opens hooks and back after it; the executor runs
on the robot's host network (the default, the node container's), so its publisher binds the
robot's own loopback and the kubelet's port-forward reaches it there.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import random
import signal
import subprocess
import sys
import threading
from collections.abc import Iterator
from typing import Any

import pytest
from coral_core.bt.groot2 import protocol
from coral_core.bt.groot2.client import Groot2Client, Groot2Error
from coral_core.bt.groot2.watching import Watcher
from coral_operator import groot2_target
from coral_testbed.cluster import Cluster, operatorchart
from coral_testbed.images import catalog
from coral_testbed.kind.missions import KindMissionStack
from coral_testbed.waiting import wait_for
from fixtures.ports import free_port_pair
from kubernetes import client as k8s
from missions import realsystems as rs

pytestmark = [pytest.mark.slow, pytest.mark.ros, pytest.mark.timeout(1800)]

ROBOT = "relay-worker"
SYSTEM = "inspection"
PORT = 1667
# The drive outlasts a few `coral tree watch` runs (each a process and a port-forward, seconds on a
# busy machine): the warmed-up tree is looked at while it still runs, before its executor ends.
TREE = """<root BTCPP_format="4" main_tree_to_execute="Main">
  <BehaviorTree ID="Main">
    <Sequence>
      <Sleep name="Warmup" msec="2000"/>
      <ForceSuccess name="Tolerate">
        <AlwaysFailure name="SafetyCheck"/>
      </ForceSuccess>
      <Sleep name="Drive" msec="20000"/>
    </Sequence>
  </BehaviorTree>
</root>
"""


def _upgrade(missions: KindMissionStack, release: operatorchart.Release) -> None:
    assert missions.cluster.bin_dir is not None
    helm = missions.cluster.bin_dir / "helm"
    operatorchart.upgrade(missions.cluster.api_client, helm, missions.cluster.env(), release)


@pytest.fixture
def hooks_policy(kind_operator: KindMissionStack, request: pytest.FixtureRequest) -> Iterator[bool]:
    """Whether the operator's policy opens Groot2 hooks for the namespace (the test's parameter);
    opened by `helm upgrade` and closed again after the test."""
    hooks: bool = request.param
    if not hooks:
        yield hooks
        return
    release = kind_operator.release
    policy = {**release.policy, "groot2HooksNamespaces": (kind_operator.namespace,)}
    _upgrade(kind_operator, dataclasses.replace(release, policy=policy))
    try:
        yield hooks
    finally:
        kind_operator.delete_systems()
        _upgrade(kind_operator, release)


def _executor(groot2: dict[str, Any]) -> dict[str, Any]:
    return {"name": "executor", "image": catalog.by_name()["executor"].reference, "groot2": groot2}


def _system(robot: str, domain: int, groot2: dict[str, Any]) -> dict[str, Any]:
    return {
        "apiVersion": f"{rs.GROUP}/{rs.VERSION}",
        "kind": "CoralSystem",
        "metadata": {"name": SYSTEM},
        "spec": {
            "robots": {"matchLabels": {"coral.dev/robot": robot}},
            "ros": {"domainId": domain},
            "parameters": {"inline": "executor:\n  ros__parameters: {}\n"},
            "tree": {"tickRateHz": 20.0, "inline": TREE},
            "executors": [_executor(groot2)],
        },
    }


def _coral(*args: str) -> list[str]:
    return [sys.executable, "-m", "coral", *args]


def _publisher(cluster: Cluster, namespace: str, robot: str) -> groot2_target.Target | None:
    """Where the robot's publisher is, once its CoralInstance names a running executor pod."""
    try:
        return groot2_target.read_target(cluster.api_client, namespace, SYSTEM, robot, None)
    except groot2_target.TargetError:
        return None


def _snapshot(cluster: Cluster, namespace: str, robot: str) -> dict[str, Any]:
    """`coral tree watch SYSTEM ROBOT --once --json`, run as a user would."""
    argv = _coral("tree", "watch", SYSTEM, robot, "-n", namespace, "--once", "--json", "--timeout", "10")
    done = subprocess.run(argv, env=cluster.env(), capture_output=True, text=True, timeout=60, check=False)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)


def _refusal(cluster: Cluster, *args: str) -> str:
    """What a `coral` verb that cannot start says; it must exit 1."""
    done = subprocess.run(_coral(*args), env=cluster.env(), capture_output=True, text=True, timeout=60)
    assert done.returncode == 1, (done.stdout, done.stderr)
    return done.stderr


def _nodes(node: dict[str, Any]) -> Iterator[dict[str, Any]]:
    yield node
    for child in node["children"]:
        yield from _nodes(child)


def _node(snapshot: dict[str, Any], name: str) -> dict[str, Any]:
    return next(n for n in _nodes(snapshot["tree"]) if n["name"] == name)


def _finished(custom: k8s.CustomObjectsApi, namespace: str) -> dict[str, Any]:
    return rs.with_root(custom, namespace, SYSTEM, "SUCCESS", "FAILURE")


class Heartbeat:
    """A second client asking for STATUS every second: any request is the publisher's heartbeat, and
    a breakpoint is released 5 s after the last one, while the test looks from outside."""

    def __init__(self, port: int) -> None:
        self.stopped = threading.Event()
        self.thread = threading.Thread(target=self._beat, args=(port,), daemon=True)
        self.thread.start()

    def _beat(self, port: int) -> None:
        with Groot2Client("127.0.0.1", port, timeout_s=10.0) as client:
            while not self.stopped.wait(1.0):
                with contextlib.suppress(Groot2Error):
                    client.status()

    def stop(self) -> None:
        self.stopped.set()
        self.thread.join(timeout=30)


class Forwarder:
    """`coral groot2 SYSTEM ROBOT --port N` as a background process, stopped with Ctrl-C (SIGINT)."""

    def __init__(self, cluster: Cluster, namespace: str, robot: str) -> None:
        self.port = free_port_pair(random.randrange(20000, 40000, 2))
        argv = _coral("groot2", SYSTEM, robot, "-n", namespace, "--port", str(self.port))
        self.process = subprocess.Popen(
            argv,
            env={**cluster.env(), "PYTHONUNBUFFERED": "1"},
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        assert self.process.stdout is not None
        # The verb prints two lines once it listens: where it forwards from, where to connect.
        self.said = [self.process.stdout.readline() for _ in range(2)]
        if not all(self.said):
            self.process.kill()
            _out, err = self.process.communicate(timeout=30)
            raise AssertionError(f"coral groot2 ended: {''.join(self.said)}{err}")

    def interrupt(self) -> tuple[int, str]:
        self.process.send_signal(signal.SIGINT)
        out, err = self.process.communicate(timeout=30)
        return self.process.returncode, "".join(self.said) + out + err

    def kill(self) -> None:
        if self.process.poll() is None:
            self.process.kill()
            self.process.communicate(timeout=30)


@pytest.fixture
def cluster(kind_operator: KindMissionStack) -> Cluster:
    return kind_operator.cluster


@pytest.fixture
def namespace(kind_operator: KindMissionStack) -> str:
    return kind_operator.namespace


@pytest.fixture
def robot(kind_operator: KindMissionStack) -> str:
    return ROBOT


@pytest.fixture
def domain(ros_env: dict[str, str]) -> int:
    return int(ros_env["ROS_DOMAIN_ID"])


@pytest.mark.parametrize("hooks_policy", [True], indirect=True, ids=["hooks-allowed"])
def test_a_breakpoint_set_from_outside_forces_a_robots_safety_check(
    hooks_policy: bool, cluster: Cluster, namespace: str, robot: str, domain: int
) -> None:
    custom = k8s.CustomObjectsApi(cluster.api_client)
    groot2 = {"port": PORT, "allowHooks": True, "waitForClientSeconds": 300}
    rs.create(custom, namespace, _system(robot, domain, groot2))
    target = wait_for(
        lambda: _publisher(cluster, namespace, robot), timeout=180, message="the executor's pod to run"
    )
    assert target.port == PORT

    forwarder = Forwarder(cluster, namespace, robot)
    try:
        assert f"127.0.0.1:{forwarder.port} and {forwarder.port + 1}" in forwarder.said[0], forwarder.said
        with Groot2Client("127.0.0.1", forwarder.port, timeout_s=10.0) as client:
            # The publisher starts once the executor loaded its tree; the mission waits for us.
            before = wait_for(
                lambda: _read(Watcher(client)),
                timeout=120,
                message="the publisher to answer through the forward",
            )
            assert before["root_status"] == "IDLE"
            safety = _node(before, "SafetyCheck")["uid"]
            client.next_breakpoint(0)  # subscribe before the breakpoint can be announced
            client.insert_hooks([protocol.HookRecord(uid=safety, mode=protocol.BREAKPOINT)])
            # Asking for STATUS keeps the heartbeat while waiting for the announcement.
            reached = wait_for(
                lambda: client.status() and client.next_breakpoint(0.5) == safety,
                timeout=60,
                message="the breakpoint on SafetyCheck to be announced",
            )
            assert reached

            # From outside, the held tree is seen to have moved on: warmed up, still RUNNING.
            heartbeat = Heartbeat(forwarder.port)
            try:
                held = _warmed_up(_snapshot(cluster, namespace, robot))
            finally:
                heartbeat.stop()
            assert held is not None and held["root_status"] == "RUNNING", held
            assert _node(held, "SafetyCheck")["status"] != "FAILURE", "the check has not run"
            client.unlock(safety, "SUCCESS")
        finished = wait_for(lambda: _finished(custom, namespace), timeout=60, message="the mission to end")
    finally:
        code, said = (
            forwarder.interrupt() if forwarder.process.poll() is None else (forwarder.process.returncode, "")
        )
        forwarder.kill()
    tree = rs.tree(finished)
    assert tree["rootStatus"] == "SUCCESS"
    assert "lastFailure" not in tree, "the forced result never failed"
    assert code == 0 and "Stopped forwarding." in said, said


@pytest.mark.parametrize("hooks_policy", [False], indirect=True, ids=["hooks-closed"])
def test_where_hooks_are_closed_they_are_refused_and_the_tree_runs_untouched(
    hooks_policy: bool, cluster: Cluster, namespace: str, robot: str, domain: int
) -> None:
    custom = k8s.CustomObjectsApi(cluster.api_client)
    rs.create(custom, namespace, _system(robot, domain, {"port": PORT, "allowHooks": True}))
    stalled = wait_for(
        lambda: _reason(custom, namespace, "Stalled") == "PolicyDenied" and _system_read(custom, namespace),
        timeout=60,
        message="the system asking for hooks to be refused",
    )
    message = rs.condition(stalled, "Stalled")["message"]
    assert (
        f"spec.executors[0] (executor): groot2.allowHooks is not allowed in namespace {namespace}" in message
    )
    assert not rs.instance(custom, namespace, SYSTEM), "nothing is deployed for a refused system"
    # Nothing to forward yet, and the verbs say why.
    unknown = _refusal(cluster, "groot2", "nosuch", robot, "-n", namespace)
    assert f"coralsystem/nosuch not found in namespace {namespace}" in unknown
    unmatched = _refusal(cluster, "tree", "watch", SYSTEM, robot, "-n", namespace, "--once")
    assert f"robot {robot} is not matched by coralsystem/{SYSTEM}" in unmatched

    watching = {"port": PORT, "waitForClientSeconds": 300}
    custom.patch_namespaced_custom_object(
        rs.GROUP,
        rs.VERSION,
        namespace,
        "coralsystems",
        SYSTEM,
        {"spec": {"executors": [_executor(watching)]}},
    )
    wait_for(lambda: _publisher(cluster, namespace, robot), timeout=180, message="the executor's pod to run")
    forwarder = Forwarder(cluster, namespace, robot)
    try:
        with Groot2Client("127.0.0.1", forwarder.port, timeout_s=10.0) as client:
            before = wait_for(lambda: _read(Watcher(client)), timeout=120, message="the publisher to answer")
            safety = _node(before, "SafetyCheck")["uid"]
            with pytest.raises(Groot2Error, match="hooks are disabled on this executor"):
                client.insert_hooks([protocol.HookRecord(uid=safety, mode=protocol.BREAKPOINT)])
            assert client.hooks() == []
        # A client that only watched releases the first tick after 3 s; the tree runs as written.
        moving = wait_for(
            lambda: _warmed_up(_snapshot(cluster, namespace, robot)),
            timeout=60,
            message="coral tree watch to show the warm-up done",
        )
        assert moving["root_status"] == "RUNNING"
        finished = wait_for(lambda: _finished(custom, namespace), timeout=60, message="the mission to end")
    finally:
        forwarder.kill()
    tree = rs.tree(finished)
    assert tree["rootStatus"] == "SUCCESS"
    assert tree["lastFailure"]["path"].endswith("SafetyCheck"), tree


def _read(watcher: Watcher) -> dict[str, Any] | None:
    try:
        return watcher.snapshot()
    except Groot2Error:
        return None


def _warmed_up(snapshot: dict[str, Any]) -> dict[str, Any] | None:
    warmup = _node(snapshot, "Warmup")
    return snapshot if "SUCCESS" in (warmup["status"], warmup.get("after")) else None


def _system_read(custom: k8s.CustomObjectsApi, namespace: str) -> dict[str, Any]:
    return custom.get_namespaced_custom_object(rs.GROUP, rs.VERSION, namespace, "coralsystems", SYSTEM)


def _reason(custom: k8s.CustomObjectsApi, namespace: str, kind: str) -> str | None:
    return rs.condition(_system_read(custom, namespace), kind).get("reason")
