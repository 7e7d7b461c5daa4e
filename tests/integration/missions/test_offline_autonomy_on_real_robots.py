"""A robot that boots without the API server runs the last revision it was given (docs/offline.md).

Power cycle here is what a robot losing power does: the kubelet, containerd, its shims and every
container die, then the robot boots again (containerd, the offline agent's boot step, the kubelet,
the agent), its link still cut. Copies of each component are counted from the robot's own runtime
(crictl against the containerd the kubelet uses) once a second for the whole test: never two at once.
"""

from __future__ import annotations

import json
import shutil
import threading
import time
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import pytest
from coral_core import offline
from coral_testbed.cluster import Cluster, realrobots
from coral_testbed.waiting import wait_for
from fixtures.operator import OperatorProcess
from fixtures.robots import REAL_ROBOT_MARKS
from kubernetes import client as k8s

from . import realsystems as rs

pytestmark = [*REAL_ROBOT_MARKS, pytest.mark.timeout(600)]

SYSTEM = "roamer"
TREE = rs.LONG_WAIT_TREE
COMPONENTS = {rs.SKILLSET, "executor"}
QUIET_SAMPLES = 20
MIN_SAMPLES = 30
SETTLED_S = 10
# Steps of the pods, not copies of a component.
HELPERS = {offline.HOLDER_CONTAINER, offline.GATE_CONTAINER, "folders-owner"}


class CopyCounter:
    """Counts each component's running containers in the robot's runtime once a second."""

    def __init__(self, robots: realrobots.RealRobots, robot: str, namespace: str) -> None:
        self.robots, self.robot, self.namespace = robots, robot, namespace
        self.samples = 0
        self.most: Counter[str] = Counter()
        self.worst: list[str] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def running(self) -> Counter[str] | None:
        """Running containers per component now; None while the runtime does not answer."""
        result = self.robots.cri(
            self.robot,
            "ps",
            "--output",
            "json",
            "--label",
            f"io.kubernetes.pod.namespace={self.namespace}",
            check=False,
            timeout=20,
        )
        if result.returncode != 0:
            return None
        containers = json.loads(result.stdout or "{}").get("containers") or []
        return Counter(c["metadata"]["name"] for c in containers if c["metadata"]["name"] not in HELPERS)

    def _run(self) -> None:
        # One sample a second on a fixed schedule: a slow answer does not push the next one back.
        due = time.monotonic()
        while not self._stop.wait(max(0.0, due - time.monotonic())):
            due += 1.0
            counts = self.running()
            if counts is None:
                continue
            self.samples += 1
            for name, count in counts.items():
                if count > self.most[name]:
                    self.most[name] = count
                if count > 1:
                    self.worst.append(f"{time.strftime('%H:%M:%S')} {dict(counts)}")

    def __enter__(self) -> CopyCounter:
        self._thread.start()
        return self

    def __exit__(self, *_: object) -> None:
        self._stop.set()
        self._thread.join(timeout=30)


def _cache(robots: realrobots.RealRobots, robot: str, namespace: str) -> Path:
    return robots.host_path(robot, f"{offline.CACHES_DIR}/{offline.cache_name(namespace, SYSTEM)}")


def _keep_only(robots: realrobots.RealRobots, robot: str, namespace: str | None) -> None:
    """Starts from a robot that stores no other system (earlier tests' systems are gone, but the
    agent forgets a system only 30 s after its last pod left)."""
    folder = robots.host_path(robot, offline.CACHES_DIR)
    if folder.is_dir():
        for cache in folder.iterdir():
            if namespace is None or cache.name != offline.cache_name(namespace, SYSTEM):
                shutil.rmtree(cache)


def _offline_system(robot: str, domain: int) -> dict[str, Any]:
    system = rs.system(SYSTEM, robot, domain, TREE)
    system["spec"]["offline"] = {"mode": "LastRevision"}
    # The hand-over may stop the offline tree (it waits ten minutes otherwise).
    system["spec"]["rollout"] = {"interruptRunningTrees": True}
    return system


def _run_until_recorded(
    custom: k8s.CustomObjectsApi, robots: realrobots.RealRobots, robot: str, namespace: str, domain: int
) -> dict[str, Any]:
    rs.create(custom, namespace, _offline_system(robot, domain))
    item = wait_for(
        lambda: (
            (i := rs.instance(custom, namespace, SYSTEM))
            and "WaitForCount" in rs.tree(i).get("activePath", "")
            and i
        ),
        timeout=240,
        interval=1,
        message=lambda: f"the mission to run: {rs.instance(custom, namespace, SYSTEM)}",
    )
    manifest = _cache(robots, robot, namespace) / offline.MANIFEST_FILE
    wait_for(
        lambda: (
            manifest.exists()
            and (recorded := json.loads(manifest.read_text()))["revision"] == item["spec"]["revision"]
            # An earlier test's system of the same name may have left its cache: this one's is new.
            and recorded["instanceUid"] == item["metadata"]["uid"]
        ),
        timeout=60,
        interval=1,
        message=f"the robot to record revision {item['spec']['revision']} of this instance in {manifest}",
    )
    return item


def _assert_nothing_runs(robots: realrobots.RealRobots, robot: str, namespace: str, what: str) -> None:
    """For 20 s after the robot booted, its runtime runs no container of the namespace (sampled
    once a second; the kubelet would have started a static pod within a few seconds)."""
    counter = CopyCounter(robots, robot, namespace)
    ticks = threading.Event()
    for _ in range(QUIET_SAMPLES):
        assert counter.running() == Counter(), what
        ticks.wait(1.0)


def _events(core: k8s.CoreV1Api, namespace: str, reason: str) -> list[Any]:
    return [e for e in core.list_namespaced_event(namespace).items if e.reason == reason]


@dataclass(frozen=True)
class Bench:
    """One robot of the session, the test's namespace and operator, the API as a user reads it."""

    robots: realrobots.RealRobots
    robot: str
    namespace: str
    domain: int
    core: k8s.CoreV1Api
    custom: k8s.CustomObjectsApi

    def parts(self) -> tuple[k8s.CoreV1Api, k8s.CustomObjectsApi, realrobots.RealRobots, str, str]:
        return self.core, self.custom, self.robots, self.robot, self.namespace


@pytest.fixture
def bench(
    cluster: Cluster,
    namespace: str,
    built_images: dict,
    real_robots: realrobots.RealRobots,
    real_robot: str,
    coral_operator: OperatorProcess,
    ros_env: dict[str, str],
) -> Iterator[Bench]:
    yield Bench(
        real_robots,
        real_robot,
        namespace,
        int(ros_env["ROS_DOMAIN_ID"]),
        k8s.CoreV1Api(cluster.api_client),
        k8s.CustomObjectsApi(cluster.api_client),
    )
    # Whatever happened, the robot ends with its link up (`real_robot` restores the rest).
    if not real_robots.link_is_up(real_robot):
        real_robots.restore_link(real_robot)


def test_a_power_cycle_while_cut_off_runs_the_last_revision_and_hands_over_with_one_copy(
    bench: Bench,
) -> None:
    core, custom, real_robots, robot, namespace = bench.parts()
    _keep_only(real_robots, robot, namespace)
    before = _run_until_recorded(custom, real_robots, robot, namespace, bench.domain)
    with CopyCounter(real_robots, robot, namespace) as copies:
        real_robots.cut_link(robot)
        booted = time.monotonic()
        real_robots.power_cycle(robot)
        wait_for(
            lambda: (c := copies.running()) is not None and all(c[name] == 1 for name in COMPONENTS),
            timeout=60 - (time.monotonic() - booted),
            interval=1,
            message=lambda: f"the components to run offline: {copies.running()}",
        )
        status = real_robots.host_path(robot, f"{offline.RUNS_DIR}/{offline.cache_name(namespace, SYSTEM)}")
        status_file = status / offline.STATUS_FILE

        def ticking() -> bool:
            if not status_file.exists():
                return False
            lines = [json.loads(line) for line in status_file.read_text().splitlines() if line.strip()]
            return any(r.get("event") == "status" and r.get("tick_count", 0) > 0 for r in lines)

        wait_for(
            ticking, timeout=60 - (time.monotonic() - booted), interval=1, message="the offline tree to tick"
        )
        print(f"offline components ran and the tree ticked {time.monotonic() - booted:.1f} s after power-on")

        real_robots.restore_link(robot)
        back = time.monotonic()
        # Timestamps on the API are whole seconds.
        back_at = datetime.now(UTC).replace(microsecond=0)

        def started_since_back(pod: Any) -> bool:
            states = [c.state.running for c in pod.status.container_statuses or []]
            return bool(states) and all(s is not None and s.started_at >= back_at for s in states)

        def converged() -> dict[str, Any]:
            item = rs.instance(custom, namespace, SYSTEM)
            if rs.condition(item, "RobotReachable").get("status") != "True":
                return {}
            pods = rs.pods(core, namespace, SYSTEM)
            by_component = Counter(p.metadata.labels.get("coral.dev/component") for p in pods)
            # The API server's copies, started after the hand-over (not the stale status of the
            # pods that died with the power).
            if by_component != Counter(COMPONENTS) or not all(started_since_back(p) for p in pods):
                return {}
            tree = rs.tree(item)
            updated = tree.get("updatedAt")
            if "WaitForCount" not in tree.get("activePath", "") or not updated:
                return {}
            if datetime.fromisoformat(updated.replace("Z", "+00:00")) < back_at:
                return {}
            return item if _events(core, namespace, "RanOffline") else {}

        item = wait_for(
            converged,
            timeout=120,
            interval=1,
            message=lambda: (
                f"reachable, one pod per component, tree running: {rs.instance(custom, namespace, SYSTEM)}"
                f"\n{[(p.metadata.name, p.status.phase) for p in rs.pods(core, namespace, SYSTEM)]}"
            ),
        )
        settled = time.monotonic()
        print(f"converged {settled - back:.1f} s after the link came back")
        # The settled robot is sampled too: a late second copy would show here.
        wait_for(
            lambda: copies.samples >= MIN_SAMPLES and time.monotonic() - settled >= SETTLED_S,
            timeout=MIN_SAMPLES + SETTLED_S,
            interval=1,
            message=lambda: f"{MIN_SAMPLES} samples ({copies.samples})",
        )
        print(f"{copies.samples} samples of the robot's runtime, at most {dict(copies.most)} per component")
    assert not copies.worst, f"two copies of a component ran at once: {copies.worst}"
    assert all(copies.most[name] == 1 for name in COMPONENTS), copies.most
    (event,) = _events(core, namespace, "RanOffline")
    assert before["spec"]["revision"] in event.message and "at tick" in event.message, event.message
    assert (
        event.involved_object.kind == "CoralInstance"
        and event.involved_object.name == item["metadata"]["name"]
    )
    report = json.loads(core.read_node(robot).metadata.annotations[offline.ANNOTATION_NODE_REPORT])
    (entry,) = report["systems"].values()
    assert entry["action"] == "RunOffline" and entry["revision"] == before["spec"]["revision"], report
    assert rs.tree(item)["tickCount"] > 0, rs.tree(item)
    rs.delete(custom, namespace, SYSTEM)


def test_a_robot_never_given_a_revision_runs_nothing_offline_and_says_so(bench: Bench) -> None:
    core, custom, real_robots, robot, namespace = bench.parts()
    _keep_only(real_robots, robot, None)
    real_robots.cut_link(robot)
    # The system is made while the robot is cut off: its pods are bound to it, it never learns them.
    rs.create(custom, namespace, _offline_system(robot, bench.domain))
    wait_for(
        lambda: len(rs.pods(core, namespace, SYSTEM)) > 0,
        timeout=60,
        message="the operator to create the system's pods",
    )
    real_robots.power_cycle(robot)
    _assert_nothing_runs(real_robots, robot, namespace, "a robot never given a revision ran something")
    static = real_robots.host_path(robot, offline.STATIC_POD_DIR)
    assert [p.name for p in static.iterdir()] == [], "static pods written for a robot with nothing stored"
    real_robots.restore_link(robot)

    def reported() -> dict[str, Any]:
        annotations = core.read_node(robot).metadata.annotations or {}
        return json.loads(annotations.get(offline.ANNOTATION_NODE_REPORT, "{}"))

    report = wait_for(
        lambda: (r := reported()) and r.get("systems", {}).get("", {}).get("action") == "NoRevision" and r,
        timeout=120,
        interval=1,
        message=lambda: f"the robot to report that it had nothing to run: {reported()}",
    )
    assert report["systems"][""]["action"] == "NoRevision"
    events = [
        e
        for e in core.list_namespaced_event("default").items
        if e.reason == "NoRevisionOffline" and e.involved_object.name == robot
    ]
    assert events and "ran nothing offline" in events[-1].message, events
    # Back online, the robot runs the system the API server gives it.
    wait_for(
        lambda: "WaitForCount" in rs.tree(rs.instance(custom, namespace, SYSTEM)).get("activePath", ""),
        timeout=240,
        interval=1,
        message=lambda: f"the mission to run once back: {rs.instance(custom, namespace, SYSTEM)}",
    )
    rs.delete(custom, namespace, SYSTEM)


def test_a_tampered_cache_is_refused_with_the_reason(bench: Bench) -> None:
    core, custom, real_robots, robot, namespace = bench.parts()
    _keep_only(real_robots, robot, namespace)
    _run_until_recorded(custom, real_robots, robot, namespace, bench.domain)
    real_robots.cut_link(robot)
    trees = sorted(_cache(real_robots, robot, namespace).glob(f"{offline.FILES_DIR}/*/*/tree.xml"))
    assert trees, "the cache holds no tree"
    # Someone on the robot swaps the mission for another one.
    trees[0].write_text(TREE.replace('threshold="1000"', 'threshold="1"'))
    real_robots.power_cycle(robot)
    _assert_nothing_runs(real_robots, robot, namespace, "a tampered cache ran")
    real_robots.restore_link(robot)
    (event,) = wait_for(
        lambda: _events(core, namespace, "OfflineCacheRefused"),
        timeout=120,
        interval=1,
        message="the robot to report the refused cache",
    )
    assert "tree.xml was altered" in event.message, event.message
    assert event.type == "Warning" and event.involved_object.kind == "CoralInstance"
    rs.delete(custom, namespace, SYSTEM)
