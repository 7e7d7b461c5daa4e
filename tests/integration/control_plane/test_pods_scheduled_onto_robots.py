"""Acceptance (a): kube-scheduler binds a Pod pinned by `coral.dev/robot` to that kwok robot, running it."""

from __future__ import annotations

import pytest
from coral_testbed.cluster import Cluster
from coral_testbed.waiting import wait_for
from kubernetes import client as k8s

from .manifests import robot_pod

pytestmark = pytest.mark.cluster


def test_pod_with_robot_node_selector_is_bound_to_that_robot_and_runs(
    cluster: Cluster, namespace: str
) -> None:
    cluster.add_robots(["r1", "r2", "r3"], {"coral.dev/model": "test-bot"})
    cluster.kubectl("apply", "-n", namespace, "-f", "-", input=robot_pod("pinned", "r1"))
    core = k8s.CoreV1Api(cluster.api_client)

    def phase() -> str | None:
        return core.read_namespaced_pod("pinned", namespace).status.phase

    wait_for(
        lambda: phase() == "Running",
        timeout=90,
        message=lambda: f"pod pinned to be Running (phase {phase()})",
    )

    pod = core.read_namespaced_pod("pinned", namespace)
    assert pod.spec.node_name == "r1"
    assert pod.status.pod_ip, "kwok should have given the running pod an IP"
    wide = cluster.kubectl(
        "get", "pod", "pinned", "-n", namespace, "-o", "wide", "--no-headers"
    ).stdout.split()
    assert wide[2] == "Running" and "r1" in wide

    # The manifest named no node: the binding must come from kube-scheduler.
    events = core.list_namespaced_event(namespace, field_selector="involvedObject.name=pinned").items
    scheduled = [e for e in events if e.reason == "Scheduled"]
    assert scheduled, [e.reason for e in events]
    assert (scheduled[0].reporting_component or scheduled[0].source.component) == "default-scheduler"
    assert "r1" in scheduled[0].message


def test_pod_for_an_absent_robot_stays_pending_with_a_scheduling_reason(
    cluster: Cluster, namespace: str
) -> None:
    cluster.kubectl("apply", "-n", namespace, "-f", "-", input=robot_pod("nowhere", "no-such-robot"))
    core = k8s.CoreV1Api(cluster.api_client)

    def unschedulable() -> bool:
        conditions = core.read_namespaced_pod("nowhere", namespace).status.conditions or []
        return any(c.type == "PodScheduled" and c.reason == "Unschedulable" for c in conditions)

    wait_for(unschedulable, timeout=60, message="pod nowhere to be reported Unschedulable")
    assert core.read_namespaced_pod("nowhere", namespace).spec.node_name is None
