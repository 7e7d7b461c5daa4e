"""A kind robot that boots without the API server runs the last revision it was given (docs/offline.md).

Every robot of the cluster runs the offline agent as its owner installs it: the systemd units of
`deploy/robot/`, the boot step after containerd and before the kubelet, the watch loop beside it.
The robot's link is cut (`docker network disconnect`) and its power lost and back inside its node
(`faults.reboot_in_place`: the kubelet, every container, containerd and the agent killed at once,
then the node's systemd boots them again). Copies of each component are counted from the robot's
own runtime (crictl against the node's containerd) once a second for the whole hand-over: never two.
"""

from __future__ import annotations

import json
import threading
import time
from collections import Counter
from collections.abc import Iterator
from datetime import UTC, datetime
from typing import Any

import pytest
from coral_core import offline
from coral_testbed.kind import clusters, faults, offlineagent
from coral_testbed.kind.missions import KindMissionStack
from coral_testbed.waiting import wait_for
from kubernetes import client as k8s
from missions import realsystems as rs

from .fleet import KindCluster, Mission

pytestmark = [pytest.mark.slow, pytest.mark.ros, pytest.mark.timeout(900)]

ROBOT = "relay-server"
SYSTEM = "roamer"
TREE = rs.LONG_WAIT_TREE
COMPONENTS = {rs.SKILLSET, "executor"}
QUIET_SAMPLES = 5
MIN_SAMPLES = 30
SETTLED_S = 10
# Steps of the pods, not copies of a component.
HELPERS = {offline.HOLDER_CONTAINER, offline.GATE_CONTAINER, "folders-owner"}


class Robot:
    """`ROBOT`'s node as someone at the robot sees it: its files, its runtime, its link."""

    def __init__(self, running: clusters.Running, namespace: str) -> None:
        self.running, self.namespace = running, namespace
        self.node = faults.node_of(running, ROBOT)

    def sh(self, script: str, check: bool = True, stdin: str | None = None) -> str:
        return self.running.engine.docker(
            "exec", "-i", self.node, "sh", "-c", script, check=check, input=stdin, timeout=30
        ).stdout

    def read(self, path: str) -> str:
        """The file's text on the robot; empty when it is missing."""
        return self.sh(f"cat {path} 2>/dev/null", check=False)

    def cache(self) -> str:
        return f"{offline.CACHES_DIR}/{offline.cache_name(self.namespace, SYSTEM)}"

    def keep_only(self, keep_this_system: bool) -> None:
        """Starts from a robot that stores no other system (earlier tests' systems are gone, but the
        agent forgets a system only 30 s after its last pod left)."""
        kept = offline.cache_name(self.namespace, SYSTEM) if keep_this_system else ""
        self.sh(
            f"find {offline.CACHES_DIR} -mindepth 1 -maxdepth 1 ! -name '{kept}' -exec rm -rf {{}} +",
            check=False,
        )

    def running_components(self) -> Counter[str] | None:
        """Running containers per component now; None while the runtime does not answer."""
        done = self.running.engine.docker(
            "exec",
            self.node,
            "crictl",
            "ps",
            "--output",
            "json",
            "--label",
            f"io.kubernetes.pod.namespace={self.namespace}",
            check=False,
            timeout=20,
        )
        if done.returncode != 0:
            return None
        containers = json.loads(done.stdout or "{}").get("containers") or []
        return Counter(c["metadata"]["name"] for c in containers if c["metadata"]["name"] not in HELPERS)

    def runtime_started(self) -> float:
        """When the robot's containerd last started, on this host's monotonic clock (the node
        container shares the host's kernel, and systemd stamps units with that clock)."""
        stamp = self.sh("systemctl show containerd.service -p ActiveEnterTimestampMonotonic --value")
        return int(stamp.strip()) / 1e6

    def runtime_view(self) -> str:
        """What a person at the robot would look at when a copy does not start: every container
        of the namespace in any state with its attempts, the executor's last output, the
        kubelet's words on the offline copies, the static pod files and pod sandboxes, and the
        agent's report."""
        return self.sh(
            f"crictl ps -a --label io.kubernetes.pod.namespace={self.namespace}; "
            f"last=$(crictl ps -a -q --name executor --label io.kubernetes.pod.namespace={self.namespace}"
            " | head -n 1); "
            '[ -n "$last" ] && crictl logs --tail 20 "$last" 2>&1; '
            # Since the boot, not the journal's last lines: a kubelet cut off from its API server
            # logs hundreds of lines a minute, which would hide how the copies started.
            "journalctl -u kubelet --no-pager --since=-5min"
            f" | grep -i '{offline.STATIC_POD_PREFIX}' | tail -n 40; "
            f"ls -l {offlineagent.STATIC_POD_DIR}; crictl pods --namespace {self.namespace}; "
            f"cat {offline.REPORT_FILE}",
            check=False,
        )


class CopyCounter:
    """Counts each component's running containers in the robot's runtime once a second."""

    def __init__(self, robot: Robot) -> None:
        self.robot = robot
        self.samples = 0
        self.most: Counter[str] = Counter()
        self.worst: list[str] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        # One sample a second on a fixed schedule: a slow answer does not push the next one back.
        due = time.monotonic()
        while not self._stop.wait(max(0.0, due - time.monotonic())):
            due += 1.0
            counts = self.robot.running_components()
            if counts is None:
                continue
            self.samples += 1
            for name, count in counts.items():
                self.most[name] = max(self.most[name], count)
                if count > 1:
                    self.worst.append(f"{time.strftime('%H:%M:%S')} {dict(counts)}")

    def __enter__(self) -> CopyCounter:
        self._thread.start()
        return self

    def __exit__(self, *_: object) -> None:
        self._stop.set()
        self._thread.join(timeout=30)


def _offline_mission(missions: KindMissionStack, domain: int) -> Mission:
    # The hand-over may stop the offline tree (it waits ten minutes otherwise).
    return Mission(
        missions,
        ROBOT,
        SYSTEM,
        domain,
        TREE,
        offline={"mode": "LastRevision"},
        rollout={"interruptRunningTrees": True},
    )


def _run_until_recorded(missions: KindMissionStack, robot: Robot, domain: int) -> dict[str, Any]:
    mission = _offline_mission(missions, domain)
    item = mission.running_in("WaitForCount", timeout=300)
    manifest = f"{robot.cache()}/{offline.MANIFEST_FILE}"

    def recorded() -> bool:
        text = robot.read(manifest)
        stored = json.loads(text) if text else {}
        # An earlier test's system of the same name may have left its cache: this one's is new.
        return (
            stored.get("revision") == item["spec"]["revision"]
            and stored.get("instanceUid") == item["metadata"]["uid"]
        )

    wait_for(
        recorded,
        timeout=60,
        interval=1,
        message=f"the robot to record revision {item['spec']['revision']} of this instance in {manifest}",
    )
    return item


def _assert_nothing_runs(robot: Robot, action: offline.BootAction, what: str) -> None:
    """The boot's decision, then its effect: the agent's report says `action` for every system it
    knows (the boot step runs before the kubelet starts), it handed the kubelet no static pod, and
    the robot's runtime runs no container of the namespace (sampled once a second for a few
    seconds, as the kubelet starts what its folder holds within a second or two)."""
    report = json.loads(robot.read(offline.REPORT_FILE) or "{}")
    assert report.get("apiReachable") is False, (what, report)
    actions = {name: entry.get("action") for name, entry in (report.get("systems") or {}).items()}
    assert actions and set(actions.values()) == {action.value}, (what, report)
    assert _static_pods(robot) == [], what
    ticks = threading.Event()
    for _ in range(QUIET_SAMPLES):
        assert robot.running_components() == Counter(), what
        ticks.wait(1.0)


def _static_pods(robot: Robot) -> list[str]:
    """The offline agent's static pods in the kubelet's static pod folder."""
    listed = robot.sh(f"ls {offlineagent.STATIC_POD_DIR}").split()
    return [name for name in listed if name.startswith(offline.STATIC_POD_PREFIX)]


def _events(core: k8s.CoreV1Api, namespace: str, reason: str) -> list[Any]:
    return [e for e in core.list_namespaced_event(namespace).items if e.reason == reason]


@pytest.fixture
def robot(kind_cluster: KindCluster, kind_operator: KindMissionStack) -> Iterator[Robot]:
    """`ROBOT`, with its link up again after the test whatever happened."""
    robot = Robot(kind_cluster.running, kind_operator.namespace)
    yield robot
    networks = kind_cluster.running.engine.docker(
        "inspect", "--format", "{{json .NetworkSettings.Networks}}", robot.node
    ).stdout
    if clusters.network_name(kind_cluster.running.name) not in networks:
        faults.restore_link(kind_cluster.running, ROBOT)


def test_a_power_cycle_while_cut_off_runs_the_last_revision_and_hands_over_with_one_copy(
    kind_cluster: KindCluster, kind_operator: KindMissionStack, robot: Robot, ros_env: dict[str, str]
) -> None:
    running, core, namespace = kind_cluster.running, kind_operator.core, kind_operator.namespace
    robot.keep_only(keep_this_system=True)
    before = _run_until_recorded(kind_operator, robot, int(ros_env["ROS_DOMAIN_ID"]))
    with CopyCounter(robot) as copies:
        faults.cut_link(running, ROBOT)
        faults.reboot_in_place(running, ROBOT)
        # The bar counts from the runtime's start, as on a robot whose power comes back.
        booted = robot.runtime_started()
        wait_for(
            lambda: (c := robot.running_components()) is not None and all(c[n] == 1 for n in COMPONENTS),
            timeout=60 - (time.monotonic() - booted),
            interval=1,
            message=lambda: (
                f"the components to run offline: {robot.running_components()}\n{robot.runtime_view()}"
            ),
        )
        status_file = f"{offline.RUNS_DIR}/{offline.cache_name(namespace, SYSTEM)}/{offline.STATUS_FILE}"

        def ticking() -> bool:
            lines = [json.loads(line) for line in robot.read(status_file).splitlines() if line.strip()]
            return any(r.get("event") == "status" and r.get("tick_count", 0) > 0 for r in lines)

        wait_for(
            ticking, timeout=60 - (time.monotonic() - booted), interval=1, message="the offline tree to tick"
        )
        print(f"offline components ran and the tree ticked {time.monotonic() - booted:.1f} s after power-on")

        faults.restore_link(running, ROBOT)
        back = time.monotonic()
        # Timestamps on the API are whole seconds.
        back_at = datetime.now(UTC).replace(microsecond=0)

        def started_since_back(pod: Any) -> bool:
            states = [c.state.running for c in pod.status.container_statuses or []]
            return bool(states) and all(s is not None and s.started_at >= back_at for s in states)

        def converged() -> dict[str, Any]:
            item = rs.instance(kind_operator.custom, namespace, SYSTEM)
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
                f"reachable, one pod per component, tree running: "
                f"{rs.instance(kind_operator.custom, namespace, SYSTEM)}"
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
    report = json.loads(core.read_node(robot.node).metadata.annotations[offline.ANNOTATION_NODE_REPORT])
    (entry,) = report["systems"].values()
    assert entry["action"] == "RunOffline" and entry["revision"] == before["spec"]["revision"], report
    assert rs.tree(item)["tickCount"] > 0, rs.tree(item)


def test_a_robot_never_given_a_revision_runs_nothing_offline_and_says_so(
    kind_cluster: KindCluster, kind_operator: KindMissionStack, robot: Robot, ros_env: dict[str, str]
) -> None:
    running, core = kind_cluster.running, kind_operator.core
    robot.keep_only(keep_this_system=False)
    faults.cut_link(running, ROBOT)
    # The system is made while the robot is cut off: its pods are bound to it, it never learns them.
    mission = _offline_mission(kind_operator, int(ros_env["ROS_DOMAIN_ID"]))
    wait_for(lambda: mission.pods(), timeout=60, message="the operator to create the system's pods")
    faults.reboot_in_place(running, ROBOT)
    _assert_nothing_runs(robot, offline.BootAction.NOTHING, "a robot never given a revision ran something")
    faults.restore_link(running, ROBOT)

    def reported() -> dict[str, Any]:
        annotations = core.read_node(robot.node).metadata.annotations or {}
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
        if e.reason == "NoRevisionOffline" and e.involved_object.name == robot.node
    ]
    assert events and "ran nothing offline" in events[-1].message, events
    # Back online, the robot runs the system the API server gives it.
    mission.running_in("WaitForCount", timeout=240)


def test_a_tampered_cache_is_refused_with_the_reason(
    kind_cluster: KindCluster, kind_operator: KindMissionStack, robot: Robot, ros_env: dict[str, str]
) -> None:
    running, core, namespace = kind_cluster.running, kind_operator.core, kind_operator.namespace
    robot.keep_only(keep_this_system=True)
    _run_until_recorded(kind_operator, robot, int(ros_env["ROS_DOMAIN_ID"]))
    faults.cut_link(running, ROBOT)
    trees = sorted(robot.sh(f"ls {robot.cache()}/{offline.FILES_DIR}/*/*/tree.xml", check=False).split())
    assert trees, "the cache holds no tree"
    # Someone on the robot swaps the mission for another one.
    robot.sh(f"cat > {trees[0]}", stdin=TREE.replace('threshold="1000"', 'threshold="1"'))
    faults.reboot_in_place(running, ROBOT)
    _assert_nothing_runs(robot, offline.BootAction.REFUSE, "a tampered cache ran")
    faults.restore_link(running, ROBOT)
    (event,) = wait_for(
        lambda: _events(core, namespace, "OfflineCacheRefused"),
        timeout=120,
        interval=1,
        message="the robot to report the refused cache",
    )
    assert "tree.xml was altered" in event.message, event.message
    assert event.type == "Warning" and event.involved_object.kind == "CoralInstance"
