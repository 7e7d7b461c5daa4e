"""A fault-free mission longer than the startup health timeout never reads Stalled, sampled every
0.5 s on a kind robot and judged by kstatus, Flux's expressions and Argo CD's health check.

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
from coral_testbed.images import catalog
from coral_testbed.kind.missions import KindMissionStack
from coral_testbed.waiting import wait_for
from kubernetes import client as k8s
from missions import realsystems as rs
from rollout import verdict_clients

from .fleet import pull_for, stops_on_sigterm

pytestmark = [pytest.mark.slow, pytest.mark.ros, pytest.mark.timeout(1800)]

ROBOT = "relay-server"
SYSTEM = "long-mission"
# The robot has the images before the system starts (`pull_for`): a short timeout then holds a
# startup on a busy machine, and a real startup timeout would fail the test for a good reason.
TIMEOUT_S = 20
DRIVER_RUNS_S = TIMEOUT_S + 15
MISSION_MS = (DRIVER_RUNS_S + 10) * 1000
TREE = rs.mission_tree('<Count count="{count}"/>', f'<Sleep msec="{MISSION_MS}"/>')


def _system(domain: int) -> dict[str, Any]:
    startup = {"healthTimeoutSeconds": TIMEOUT_S, "onTimeout": "Block"}
    system = rs.system(SYSTEM, ROBOT, domain, TREE, startup=startup)
    # A bag player's part: ready while it plays, then done (exit 0).
    system["spec"]["drivers"] = [
        {
            "name": "player",
            "image": catalog.by_name()["examples-skillset"].reference,
            "command": ["sh", "-c", stops_on_sigterm(f"sleep {DRIVER_RUNS_S}")],
            "transient": True,
        }
    ]
    return system


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
                rs.GROUP, rs.VERSION, self.namespace, "coralsystems", SYSTEM
            )
            instance = rs.instance(self.custom, self.namespace, SYSTEM)
            self.samples.append((time.monotonic() - started, system, instance))

    def root(self) -> str | None:
        return rs.tree(self.samples[-1][2]).get("rootStatus") if self.samples else None


def _stalled(obj: dict[str, Any]) -> dict[str, Any] | None:
    condition = rs.condition(obj, "Stalled")
    return condition if condition.get("status") == "True" else None


def test_a_mission_longer_than_the_health_timeout_never_reads_stalled(
    kind_operator: KindMissionStack, ros_env: dict[str, str]
) -> None:
    custom, core, namespace = kind_operator.custom, kind_operator.core, kind_operator.namespace
    manifest = _system(int(ros_env["ROS_DOMAIN_ID"]))
    pull_for(kind_operator, [ROBOT], manifest)
    rs.create(custom, namespace, manifest)
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
    (driver,) = rs.pods(core, namespace, SYSTEM, "player")
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
