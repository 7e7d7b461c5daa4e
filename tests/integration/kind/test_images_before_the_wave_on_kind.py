"""Images before the wave (`spec.rollout.prePull`) on two kind robots, with a slowed registry.

Revision 1 runs the example skillset and the executor from the cluster's registry under their usual
names. Revision 2 names the same images at the registry's own address (the network's gateway, which
every robot's containerd knows as plain HTTP): names no robot has, so both pull. Inside the first
robot's network namespace its connections to that address are diverted to a proxy of this test on
the gateway, which sends at most `RATE` bytes a second from the registry; inside the second's they
are refused. With `prePull: BeforeRollout`, no component pod of revision 2 may exist anywhere while
the first robot still pulls; `coral rollout status` shows the pull; once the first robot has its
images and the second failed, the first moves and the second stays on revision 1 with the
kubelet's message on its CoralInstance.
"""

from __future__ import annotations

import contextlib
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from typing import Any

import pytest
from coral_testbed.kind.missions import KindMissionStack
from coral_testbed.waiting import wait_for
from kubernetes import client as k8s
from missions import realsystems as rs

from . import pullfailures
from .fleet import on_robot

pytestmark = [pytest.mark.slow, pytest.mark.ros, pytest.mark.timeout(600)]

SYSTEM = "prepulled"
SLOWED, REFUSED = "relay-survey", "relay-server"
"""The robot that pulls through the slowed proxy, and the one whose registry refuses it."""
RATE = 256
"""Bytes a second the slowed registry sends on each connection: the first robot's pull of the two
images' manifests and configs takes about 12 s, the time `coral rollout status` has to show it."""
PROXY_LIFETIME_S = 300.0
"""The proxy stops serving after this long whatever happens (every fault here is bounded)."""
TREE = rs.mission_tree('<Count count="{count}"/>')
PREPULL_ROLE = "prepull"


def _throttled(source: socket.socket, sink: socket.socket, rate: int, until: float) -> None:
    try:
        while time.monotonic() < until and (data := source.recv(rate // 4 or 1)):
            sink.sendall(data)
            # The pace of the slowed link itself, not a wait for another party.
            time.sleep(len(data) / rate)
    except OSError:
        pass
    finally:
        for end in (source, sink):
            with contextlib.suppress(OSError):
                end.shutdown(socket.SHUT_RDWR)


@contextlib.contextmanager
def slowed_registry(registry_address: str, rate: int) -> Iterator[int]:
    """A port of the registry's host (the cluster network's gateway) that forwards to the registry,
    its answers at `rate` bytes a second."""
    host, _, port = registry_address.rpartition(":")
    server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    server.bind((host, 0))
    server.listen(16)
    until = time.monotonic() + PROXY_LIFETIME_S

    def serve() -> None:
        while True:
            try:
                client, _ = server.accept()
                upstream = socket.create_connection((host, int(port)), timeout=10)
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


def _system(domain: int, rollout: dict[str, Any], registry: str | None = None) -> dict[str, Any]:
    manifest = rs.system(SYSTEM, SLOWED, domain, TREE)
    spec = manifest["spec"]
    spec["robots"] = {
        "matchExpressions": [{"key": "coral.dev/robot", "operator": "In", "values": [SLOWED, REFUSED]}]
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


def _system_now(custom: k8s.CustomObjectsApi, namespace: str) -> dict[str, Any]:
    return custom.get_namespaced_custom_object(rs.GROUP, rs.VERSION, namespace, "coralsystems", SYSTEM)


@pytest.fixture
def renamed_images(kind_operator: KindMissionStack) -> Iterator[str]:
    """The registry's own address, under which revision 2 names its images; those names are taken
    off both robots afterwards, so the next test finds them as this one did."""
    registry = kind_operator.running.registry_address
    yield registry
    kind_operator.delete_systems()
    spec = _system(0, {}, registry)["spec"]
    for robot in (SLOWED, REFUSED):
        for component in [*spec["skillsets"], *spec["executors"]]:
            on_robot(kind_operator.running, robot, "crictl", "rmi", component["image"], check=False)


def test_a_rollout_with_pre_pull_moves_no_robot_before_its_images_are_there(
    kind_operator: KindMissionStack, renamed_images: str, ros_env: dict[str, str]
) -> None:
    core, custom, namespace = kind_operator.core, kind_operator.custom, kind_operator.namespace
    running = kind_operator.running
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
    with (
        slowed_registry(running.registry_address, RATE) as slow,
        pullfailures.registry_diverted(running, SLOWED, slow),
        pullfailures.registry_refused(running, REFUSED),
    ):
        body = _system_now(custom, namespace)
        body["spec"] = _system(domain, rollout, renamed_images)["spec"]
        custom.replace_namespaced_custom_object(rs.GROUP, rs.VERSION, namespace, "coralsystems", SYSTEM, body)
        changed = time.monotonic()
        new = wait_for(
            lambda: (
                (status := _system_now(custom, namespace).get("status", {}).get("rollout", {}))
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
            pod = _pre_pull_pod(core, namespace, SLOWED)
            pull_pod = pod.metadata.uid if pod is not None else pull_pod
            moved = _component_pods_of(core, namespace, new)
            pulled = pod is not None and pod.status.phase in ("Succeeded", "Failed")
            if pulled or (pod is None and moved):
                break
            assert not moved, f"revision 2 pods started while the first robot still pulls: {moved}"
            samples += 1
            if not shown and pod is not None:
                argv = [sys.executable, "-m", "coral", "rollout", "status", SYSTEM, "-n", namespace]
                env = kind_operator.cluster.env()
                said = subprocess.run(argv, env=env, capture_output=True, text=True, timeout=60)
                if "pulling" in said.stdout:
                    shown = said.stdout
            assert time.monotonic() - changed < 240, "the first robot's pull to end"
            # Sampling pace: every sample checks that nothing moved while the pull runs.
            time.sleep(0.5)
        pull_s = time.monotonic() - changed
        print(f"first robot's images present {pull_s:.1f} s after the change ({samples} samples, none moved)")
        assert shown, "coral rollout status showed the pull while it ran"
        assert f"pre-pull of revision {new}: images on" in shown and "pulling" in shown, shown
        print(shown)
        wait_for(
            lambda: _instances(custom, namespace)[SLOWED]["spec"]["revision"] == new,
            timeout=60,
            message="the first robot moves once its images are there",
        )
        wait_for(
            lambda: (
                rs.tree(_instances(custom, namespace)[SLOWED]).get("rootStatus") == "SUCCESS"
                and _instances(custom, namespace)[SLOWED]["status"].get("revision") == new
            ),
            timeout=180,
            interval=1,
            message=lambda: f"revision 2 runs on the first robot: {_instances(custom, namespace)}",
        )
        second = _instances(custom, namespace)[REFUSED]
        assert second["spec"]["revision"] == old[REFUSED], "the robot whose pull failed stays"
        told = rs.condition(second, "ImagesPrePulled")
        assert told.get("status") == "False" and told.get("reason") == "ImagePullFailed", told
        assert renamed_images in told["message"], told
        # The kubelet's own record: every image of the first robot was pulled before its first pod
        # of revision 2 was created (both to the second, as the API server stamps them).
        pulled_at = [
            e.last_timestamp or e.event_time
            for e in core.list_namespaced_event(
                namespace, field_selector=f"involvedObject.uid={pull_pod}"
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
        node = first[SLOWED]["spec"]["nodeName"]
        elsewhere = [p for p in _component_pods_of(core, namespace, new) if not p.startswith(f"{node}/")]
        assert not elsewhere, f"revision 2 runs only where its images were pulled: {elsewhere}"
        rollout_status = _system_now(custom, namespace)["status"]["rollout"]
        pre_pull = rollout_status["prePull"]
        assert pre_pull["failed"] == 1 and pre_pull["failures"][0]["robot"] == REFUSED, pre_pull
        print(f"second robot: {told['message']}")
        print(f"status.rollout.message: {rollout_status['message']}")
    rs.delete(custom, namespace, SYSTEM)
