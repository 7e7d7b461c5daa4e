"""A fault-free mission longer than the startup health timeout never reads Stalled, sampled every
0.5 s on a real robot and judged by kstatus, Flux's expressions and Argo CD's health check.

Issue 50: the timeout counted from each pod's creation for the pod's whole life, so every mission
longer than it ended with about a second of `Stalled=True` (13 runs of 13): when the transient bag
player exits, its pod is unready for the second before the kubelet calls it Succeeded. Here a
transient driver exits well past a short timeout, while the executor's tree is still running.
"""

from __future__ import annotations

import threading
import time
from typing import Any

import pytest
import verdict_clients
from coral_testbed.cluster import Cluster, realrobots
from coral_testbed.images import catalog
from coral_testbed.waiting import wait_for
from fixtures.operator import OperatorProcess
from fixtures.robots import REAL_ROBOT_MARKS, REAL_ROBOTS, pull_images
from kubernetes import client as k8s

pytestmark = [*REAL_ROBOT_MARKS, pytest.mark.timeout(480)]

GROUP, VERSION = "coral.dev", "v1alpha1"
SYSTEM = "long-mission"
# The robot has the images before the system starts (`pull_images`): a short timeout then holds
# a startup on a busy machine, and a real startup timeout would fail the test for a good reason.
TIMEOUT_S = 30
DRIVER_RUNS_S = TIMEOUT_S + 20
MISSION_MS = (DRIVER_RUNS_S + 15) * 1000
TREE = f"""<root BTCPP_format="4" main_tree_to_execute="Main">
  <BehaviorTree ID="Main">
    <Sequence>
      <Count count="{{count}}"/>
      <Sleep msec="{MISSION_MS}"/>
    </Sequence>
  </BehaviorTree>
</root>
"""


def _system(robot: str, domain: int) -> dict[str, Any]:
    images = catalog.by_name()
    skillset = images["examples-skillset"].reference
    return {
        "apiVersion": f"{GROUP}/{VERSION}",
        "kind": "CoralSystem",
        "metadata": {"name": SYSTEM},
        "spec": {
            "robots": {"matchLabels": {"coral.dev/robot": robot}},
            "ros": {"domainId": domain},
            "parameters": {"inline": "examples:\n  ros__parameters: {}\n"},
            "tree": {"tickRateHz": 10.0, "inline": TREE},
            "startup": {"healthTimeoutSeconds": TIMEOUT_S, "onTimeout": "Block"},
            # A bag player's part: ready while it plays, then done (exit 0).
            "drivers": [
                {
                    "name": "player",
                    "image": skillset,
                    "command": ["sh", "-c", f"sleep {DRIVER_RUNS_S}"],
                    "transient": True,
                }
            ],
            "skillsets": [
                {"name": "examples", "image": skillset, "args": ["--params", "/etc/coral/params.yaml"]}
            ],
            "executors": [{"name": "executor", "image": images["executor"].reference}],
        },
    }


class Sampler:
    """Reads the system and its instance every 0.5 s on a thread, as a GitOps client polls them."""

    def __init__(self, custom: k8s.CustomObjectsApi, namespace: str) -> None:
        self.custom, self.namespace = custom, namespace
        self.samples: list[tuple[float, dict[str, Any], dict[str, Any]]] = []
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        started = time.monotonic()
        while not self.stop.wait(0.5):
            system = self.custom.get_namespaced_custom_object(
                GROUP, VERSION, self.namespace, "coralsystems", SYSTEM
            )
            listed = self.custom.list_namespaced_custom_object(
                GROUP, VERSION, self.namespace, "coralinstances"
            )
            instance = next(iter(listed["items"]), {})
            self.samples.append((time.monotonic() - started, system, instance))

    def root(self) -> str | None:
        if not self.samples:
            return None
        tree = (self.samples[-1][2].get("status") or {}).get("tree") or {}
        return tree.get("rootStatus")


def _stalled(obj: dict[str, Any]) -> dict[str, Any] | None:
    for condition in (obj.get("status") or {}).get("conditions") or []:
        if condition.get("type") == "Stalled" and condition.get("status") == "True":
            return condition
    return None


def test_a_mission_longer_than_the_health_timeout_never_reads_stalled(
    cluster: Cluster,
    namespace: str,
    built_images: dict[str, Any],
    real_robots: realrobots.RealRobots,
    coral_operator: OperatorProcess,
    ros_env: dict[str, str],
) -> None:
    robot = REAL_ROBOTS[0] if REAL_ROBOTS[0] in real_robots.names() else sorted(real_robots.names())[0]
    custom, core = k8s.CustomObjectsApi(cluster.api_client), k8s.CoreV1Api(cluster.api_client)
    manifest = _system(robot, int(ros_env["ROS_DOMAIN_ID"]))
    spec = manifest["spec"]
    images = {c["image"] for group in ("drivers", "skillsets", "executors") for c in spec[group]}
    pull_images(cluster, namespace, robot, sorted(images | {coral_operator.extra_env["CORAL_HELPER_IMAGE"]}))
    custom.create_namespaced_custom_object(GROUP, VERSION, namespace, "coralsystems", manifest)
    sampler = Sampler(custom, namespace)
    sampler.thread.start()
    try:
        wait_for(
            lambda: sampler.root() == "SUCCESS",
            timeout=TIMEOUT_S + MISSION_MS / 1000 + 180,
            interval=1,
            message=lambda: f"the mission to succeed: {sampler.samples[-1:] or 'no sample yet'}",
        )
        # A few more samples: the moments after the mission are where the blip used to be.
        seen = len(sampler.samples)
        wait_for(lambda: len(sampler.samples) >= seen + 6, timeout=30, message="samples after the end")
    finally:
        sampler.stop.set()
        sampler.thread.join(timeout=10)
    (driver,) = core.list_namespaced_pod(namespace, label_selector="coral.dev/component=player").items
    assert driver.status.phase == "Succeeded", "the transient driver finished during the mission"
    took = sampler.samples[-1][0]
    assert took > 2 * TIMEOUT_S, f"the mission lasted {took:.0f} s, longer than the timeout twice over"
    stalled = [
        (at, kind, condition)
        for at, system, instance in sampler.samples
        for kind, condition in (("system", _stalled(system)), ("instance", _stalled(instance)))
        if condition
    ]
    assert not stalled, f"Stalled at some moment (seconds in, object, condition): {stalled[:5]}"
    objects = [obj for _, system, instance in sampler.samples for obj in (system, instance) if obj]
    failed = [
        (obj["kind"], judged["kstatus"], judged["flux"], judged["argo"])
        for obj, judged in zip(objects, verdict_clients.judge_all(objects), strict=True)
        if "Failed" in (judged["kstatus"]["status"], judged["flux"]["status"])
        or judged["argo"]["status"] == "Degraded"
    ]
    assert not failed, f"{len(failed)} of {len(objects)} samples judged failed: {failed[:3]}"
    print(f"{len(sampler.samples)} samples over {took:.0f} s, none Stalled or failed to any client")
    custom.delete_namespaced_custom_object(GROUP, VERSION, namespace, "coralsystems", SYSTEM)
