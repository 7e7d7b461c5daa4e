"""Images before the wave (`spec.rollout.prePull`) on the session's two real robots, with a slowed registry.

Revision 1 runs the example skillset and the executor from the session's registry. Revision 2 names
the same images at a port of each robot's loopback: on the first robot that port leads, through a
proxy of this test that sends at most `RATE` bytes a second, to the registry; on the second nothing
listens there (its containerd's connection is refused). With `prePull: BeforeRollout`, no component
pod of revision 2 may exist anywhere while the first robot still pulls; `coral rollout status` shows
the pull; once the first robot has its images and the second failed, the first moves and the second
stays on revision 1 with the kubelet's message on its CoralInstance.
"""

from __future__ import annotations

import contextlib
import shutil
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from typing import Any

import pytest
from coral_testbed.cluster import Cluster, realrobots, uplink
from coral_testbed.waiting import wait_for
from fixtures.operator import OperatorProcess
from fixtures.robots import REAL_ROBOT_MARKS, REAL_ROBOTS
from kubernetes import client as k8s

from . import realsystems as rs

pytestmark = [*REAL_ROBOT_MARKS, pytest.mark.timeout(480)]

SYSTEM = "prepulled"
RATE = 512
"""Bytes a second the slowed registry sends on each connection: a manifest takes seconds."""
PROXY_LIFETIME_S = 300.0
"""The proxy stops serving after this long whatever happens (every fault here is bounded)."""
TREE = rs.mission_tree('<Count count="{count}"/>')
PREPULL_ROLE = "prepull"


def _throttled(source: socket.socket, sink: socket.socket, rate: int, until: float) -> None:
    try:
        while time.monotonic() < until and (data := source.recv(rate // 4 or 1)):
            sink.sendall(data)
            time.sleep(len(data) / rate)
    except OSError:
        pass
    finally:
        for end in (source, sink):
            with contextlib.suppress(OSError):
                end.shutdown(socket.SHUT_RDWR)


@contextlib.contextmanager
def slowed_registry(registry_port: int, rate: int) -> Iterator[int]:
    """A port of 127.0.0.1 that forwards to the registry, its answers at `rate` bytes a second."""
    server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    server.bind(("127.0.0.1", 0))
    server.listen(16)
    until = time.monotonic() + PROXY_LIFETIME_S

    def serve() -> None:
        while True:
            try:
                client, _ = server.accept()
                upstream = socket.create_connection(("127.0.0.1", registry_port), timeout=10)
            except OSError:
                return
            upstream.settimeout(None)
            threading.Thread(target=_throttled, args=(client, upstream, 1 << 20, until), daemon=True).start()
            threading.Thread(target=_throttled, args=(upstream, client, rate, until), daemon=True).start()

    threading.Thread(target=serve, daemon=True).start()
    try:
        yield server.getsockname()[1]
    finally:
        with contextlib.suppress(OSError):
            server.shutdown(socket.SHUT_RDWR)
        server.close()


@pytest.fixture
def loopback_port(real_robots: realrobots.RealRobots) -> Iterator[int]:
    """A port free on both robots' loopback, known to both containerds as a plain-HTTP registry."""
    layouts = [real_robots.layout(robot) for robot in REAL_ROBOTS]
    probe = uplink.listen_inside(str(layouts[0].link.netns_path), 0)
    port = probe.getsockname()[1]
    probe.close()
    folders = []
    for layout in layouts:
        folder = layout.registry_hosts_dir / f"127.0.0.1:{port}"
        folder.mkdir(parents=True)
        (folder / "hosts.toml").write_text(f'server = "http://127.0.0.1:{port}"\n')
        folders.append(folder)
    yield port
    for folder in folders:
        shutil.rmtree(folder)


def _system(domain: int, rollout: dict[str, Any], registry: str | None = None) -> dict[str, Any]:
    manifest = rs.system(SYSTEM, REAL_ROBOTS[0], domain, TREE)
    spec = manifest["spec"]
    spec["robots"] = {
        "matchExpressions": [{"key": "coral.dev/robot", "operator": "In", "values": list(REAL_ROBOTS)}]
    }
    spec["rollout"] = rollout
    if registry is not None:
        for component in [*spec["skillsets"], *spec["executors"]]:
            component["image"] = f"{registry}/{component['image']}"
    return manifest


def _instances(custom: k8s.CustomObjectsApi, namespace: str) -> dict[str, dict[str, Any]]:
    items = custom.list_namespaced_custom_object(rs.GROUP, rs.VERSION, namespace, "coralinstances")["items"]
    return {i["spec"]["robot"]: i for i in items}


def _component_pods_of(core: k8s.CoreV1Api, namespace: str, revision: str) -> list[str]:
    return [
        f"{p.spec.node_name}/{p.metadata.name}"
        for p in rs.pods(core, namespace, SYSTEM)
        if p.metadata.labels.get("coral.dev/revision") == revision
        and p.metadata.labels.get("coral.dev/role") != PREPULL_ROLE
    ]


def _pre_pull_pod(core: k8s.CoreV1Api, namespace: str, robot: str) -> Any:
    selector = f"coral.dev/role={PREPULL_ROLE},coral.dev/robot={robot}"
    return next(iter(core.list_namespaced_pod(namespace, label_selector=selector).items), None)


def test_a_rollout_with_pre_pull_moves_no_robot_before_its_images_are_there(
    cluster: Cluster,
    namespace: str,
    built_images: dict[str, Any],
    real_robots: realrobots.RealRobots,
    coral_operator: OperatorProcess,
    loopback_port: int,
    image_registry: str,
    ros_env: dict[str, str],
) -> None:
    core, custom = k8s.CoreV1Api(cluster.api_client), k8s.CustomObjectsApi(cluster.api_client)
    domain = int(ros_env["ROS_DOMAIN_ID"])
    rollout = {"maxUnavailable": "100%", "prePull": {"when": "BeforeRollout", "deadlineSeconds": 240}}
    rs.create(custom, namespace, _system(domain, rollout))
    first = wait_for(
        lambda: (
            (found := _instances(custom, namespace))
            and len(found) == 2
            and all(rs.tree(i).get("rootStatus") == "SUCCESS" for i in found.values())
            and found
        ),
        timeout=240,
        interval=1,
        message=lambda: f"revision 1 runs on both robots: {_instances(custom, namespace)}",
    )
    old = {robot: item["spec"]["revision"] for robot, item in first.items()}
    netns = str(real_robots.layout(REAL_ROBOTS[0]).link.netns_path)
    registry_port = int(image_registry.rpartition(":")[2])
    with slowed_registry(registry_port, RATE) as slow, uplink.offered_inside(netns, loopback_port, slow):
        body = custom.get_namespaced_custom_object(rs.GROUP, rs.VERSION, namespace, "coralsystems", SYSTEM)
        body["spec"] = _system(domain, rollout, f"127.0.0.1:{loopback_port}")["spec"]
        custom.replace_namespaced_custom_object(rs.GROUP, rs.VERSION, namespace, "coralsystems", SYSTEM, body)
        changed = time.monotonic()
        new = wait_for(
            lambda: (
                (status := rs_system(custom, namespace).get("status", {}).get("rollout", {}))
                and status.get("revision") not in old.values()
                and status.get("revision")
            ),
            timeout=60,
            message="the operator to see revision 2",
        )
        # While the first robot pulls through the slowed registry, nothing of revision 2 may start.
        shown = ""
        samples = 0
        pull_pod = ""
        while True:
            pod = _pre_pull_pod(core, namespace, REAL_ROBOTS[0])
            pull_pod = pod.metadata.name if pod is not None else pull_pod
            moved = _component_pods_of(core, namespace, new)
            pulled = pod is not None and pod.status.phase in ("Succeeded", "Failed")
            if pulled or (pod is None and moved):
                break
            assert not moved, f"revision 2 pods started while the first robot still pulls: {moved}"
            samples += 1
            if not shown and pod is not None:
                argv = [sys.executable, "-m", "coral", "rollout", "status", SYSTEM, "-n", namespace]
                said = subprocess.run(argv, env=cluster.env(), capture_output=True, text=True, timeout=60)
                if "pulling" in said.stdout:
                    shown = said.stdout
            assert time.monotonic() - changed < 240, "the first robot's pull to end"
            time.sleep(0.5)
        pull_s = time.monotonic() - changed
        print(f"first robot's images present {pull_s:.1f} s after the change ({samples} samples, none moved)")
        assert shown, "coral rollout status showed the pull while it ran"
        assert f"pre-pull of revision {new}: images on" in shown and "pulling" in shown, shown
        print(shown)
        wait_for(
            lambda: _instances(custom, namespace)[REAL_ROBOTS[0]]["spec"]["revision"] == new,
            timeout=60,
            message="the first robot moves once its images are there",
        )
        wait_for(
            lambda: (
                rs.tree(_instances(custom, namespace)[REAL_ROBOTS[0]]).get("rootStatus") == "SUCCESS"
                and _instances(custom, namespace)[REAL_ROBOTS[0]]["status"].get("revision") == new
            ),
            timeout=180,
            interval=1,
            message=lambda: f"revision 2 runs on the first robot: {_instances(custom, namespace)}",
        )
        second = _instances(custom, namespace)[REAL_ROBOTS[1]]
        assert second["spec"]["revision"] == old[REAL_ROBOTS[1]], "the robot whose pull failed stays"
        told = rs.condition(second, "ImagesPrePulled")
        assert told.get("status") == "False" and told.get("reason") == "ImagePullFailed", told
        assert f"127.0.0.1:{loopback_port}" in told["message"], told
        # The kubelet's own record: every image of the first robot was pulled before its first pod
        # of revision 2 was created (both to the second, as the API server stamps them).
        pulled_at = [
            e.last_timestamp or e.event_time
            for e in core.list_namespaced_event(
                namespace, field_selector=f"involvedObject.name={pull_pod}"
            ).items
            if e.reason == "Pulled"
        ]
        assert len(pulled_at) == 2, f"one Pulled event per image of revision 2: {pulled_at}"
        created = [
            p.metadata.creation_timestamp
            for p in rs.pods(core, namespace, SYSTEM)
            if p.metadata.labels.get("coral.dev/revision") == new
            and p.metadata.labels.get("coral.dev/role") != PREPULL_ROLE
        ]
        assert created and min(created) >= max(pulled_at), (pulled_at, created)
        node = first[REAL_ROBOTS[0]]["spec"]["nodeName"]
        elsewhere = [p for p in _component_pods_of(core, namespace, new) if not p.startswith(f"{node}/")]
        assert not elsewhere, f"revision 2 runs only where its images were pulled: {elsewhere}"
        rollout_status = rs_system(custom, namespace)["status"]["rollout"]
        pre_pull = rollout_status["prePull"]
        assert pre_pull["failed"] == 1 and pre_pull["failures"][0]["robot"] == REAL_ROBOTS[1], pre_pull
        print(f"second robot: {told['message']}")
        print(f"status.rollout.message: {rollout_status['message']}")
    rs.delete(custom, namespace, SYSTEM)


def rs_system(custom: k8s.CustomObjectsApi, namespace: str) -> dict[str, Any]:
    return custom.get_namespaced_custom_object(rs.GROUP, rs.VERSION, namespace, "coralsystems", SYSTEM)
