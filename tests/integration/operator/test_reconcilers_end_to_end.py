"""Each kind's reconciler end to end on the real control plane, with kwok robots.

A CoralSystem: its robots get instances, one counted Event tells of them, a spec change moves every
robot and the system is Ready again at the new revision. A CoralInstance: it starts its robot's
pods and becomes Ready, and its status is written when a verdict changes, not on every pod event.
"""

from __future__ import annotations

import threading
import time
from typing import Any

import pytest
from coral_api import GROUP, VERSION, is_current_and_true
from coral_operator.planning import status_pacing
from coral_operator.status import ownership
from kubernetes import client as k8s
from kubernetes import watch
from scenarios import Scenario
from urllib3.exceptions import ProtocolError

pytestmark = [pytest.mark.cluster, pytest.mark.slow]
# Progress alone is written at most this often (planning.status_pacing.progress_interval: 10 s, then
# longer), less the time a watch event takes to arrive.
PROGRESS_WRITE_S = 9.0


def _events(cluster: Any, namespace: str, name: str, reason: str) -> list[Any]:
    core = k8s.CoreV1Api(cluster.api_client)
    selector = f"involvedObject.name={name},reason={reason}"
    return core.list_namespaced_event(namespace, field_selector=selector).items


def test_a_system_deploys_counts_its_robots_in_one_event_and_follows_a_spec_change(
    scenario: Scenario,
) -> None:
    cluster, namespace, coral, wait = scenario.cluster, scenario.namespace, scenario.coral, scenario.wait
    fleet = scenario.robots(3)
    coral.create_system(scenario.mission("fleet"))
    system = wait(
        lambda: (s := coral.system("fleet")) and is_current_and_true(s, "Ready") and s,
        "the system to become Ready",
    )
    assert system["status"]["robots"]["matched"] == 3 and system["status"]["robots"]["ready"] == 3
    assert sorted(i["spec"]["robot"] for i in coral.instances().values()) == sorted(fleet)
    created = wait(
        lambda: _events(cluster, namespace, "fleet", "InstancesCreated"), "an InstancesCreated Event"
    )
    assert sum(int(e.message.split()[1]) * (e.count or 1) for e in created) == 3, [e.message for e in created]
    first = system["status"]["revision"]
    # Who wrote an instance is named in its managedFields (and in audit logs) as the operator.
    managers = {
        entry["manager"]
        for instance in coral.instances().values()
        for entry in instance["metadata"].get("managedFields") or []
    }
    assert "coral-operator" in managers and "OpenAPI-Generator" not in managers, managers

    skillset = system["spec"]["skillsets"][0]
    env = [*skillset.get("env", []), {"name": "MODE", "value": "changed"}]
    coral.patch_system("fleet", {"spec": {"skillsets": [{**skillset, "env": env}]}})
    system = wait(
        lambda: (
            (s := coral.system("fleet"))
            and is_current_and_true(s, "Ready")
            and s["status"].get("revision") != first
            and s["status"]["robots"]["updated"] == 3
            and s
        ),
        "every robot at the new revision and the system Ready again",
        timeout=120,
    )
    revision = system["status"]["revision"]
    assert {i["spec"]["revision"] for i in coral.instances().values()} == {revision}
    assert wait(lambda: _events(cluster, namespace, "fleet", "InstancesUpdated"), "an InstancesUpdated Event")


class StatusRecorder:
    """Watches one namespace's CoralInstances and keeps each status change of one of them."""

    def __init__(self, cluster: Any, namespace: str) -> None:
        self.custom = k8s.CustomObjectsApi(cluster.api_client)
        self.namespace = namespace
        self.seen: dict[str, list[tuple[float, dict[str, Any]]]] = {}
        self._watch = watch.Watch()
        self._stopped = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def __enter__(self) -> StatusRecorder:
        self._thread.start()
        return self

    def __exit__(self, *_: Any) -> None:
        self._stopped.set()
        self._watch.stop()
        self._thread.join(10)

    def _run(self) -> None:
        try:
            self._record()
        except ProtocolError:
            if not self._stopped.is_set():
                raise  # the stream broke while recording, not because the test stopped it

    def _record(self) -> None:
        stream = self._watch.stream(
            self.custom.list_namespaced_custom_object,
            GROUP,
            VERSION,
            self.namespace,
            "coralinstances",
            timeout_seconds=300,
        )
        for event in stream:
            item = event["object"]
            status = ownership.operator_part(item.get("status") or {})
            history = self.seen.setdefault(item["metadata"]["name"], [])
            if not history or history[-1][1] != status:
                history.append((time.monotonic(), status))


def test_an_instance_starts_its_robot_and_writes_status_once_per_verdict_change(
    scenario: Scenario,
) -> None:
    coral, wait = scenario.coral, scenario.wait
    (robot,) = scenario.robots(1)
    with StatusRecorder(scenario.cluster, scenario.namespace) as recorder:
        coral.create_system(scenario.mission("solo"))
        instance = wait(
            lambda: (i := coral.instances().get(f"solo-{robot}")) and is_current_and_true(i, "Ready") and i,
            "the robot's instance to become Ready",
        )
        name = instance["metadata"]["name"]
        wait(
            lambda: (
                recorder.seen.get(name)
                and recorder.seen[name][-1][1] == ownership.operator_part(instance["status"])
            ),
            "the watch to see the Ready status",
        )
    pods = [p for p in coral.pods().values() if p.metadata.labels.get("coral.dev/instance") == name]
    assert sorted(p.metadata.labels["coral.dev/role"] for p in pods) == ["driver", "executor", "skillset"]
    assert [c["ready"] for c in instance["status"]["components"]] == [True] * len(
        instance["status"]["components"]
    )

    history = [entry for entry in recorder.seen[name] if entry[1]]
    assert len(history) >= 2, "the first status and the Ready one were not both seen"
    for (before_at, before), (after_at, after) in zip(history, history[1:], strict=False):
        verdict_changed = status_pacing.verdict_of(before) != status_pacing.verdict_of(after)
        assert verdict_changed or after_at - before_at >= PROGRESS_WRITE_S, (
            "a status write without a verdict change came early",
            before,
            after,
        )
