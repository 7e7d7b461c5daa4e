"""Watch events become keys on the one work queue: a pass on new inputs only, and again after a failure.

The controller's queue is not started in most of these tests, so what the events queued can be read
from it; no cluster is needed (events are built as kopf hands them over).
"""

from __future__ import annotations

import threading
from typing import Any

from coral_operator.kube import observing
from coral_operator.planning.policy import Policy
from coral_operator.reconcile.controller import INSTANCE, SYSTEM, Controller
from coral_operator.reconcile.indexes import instances_on_node


def _controller() -> Controller:
    return Controller(policy=Policy(), post=lambda *_: None)


def _system(generation: int, annotations: dict[str, str] | None = None) -> dict[str, Any]:
    return {"metadata": {"generation": generation, "annotations": annotations or {}}}


def _instance(ready: str = "False", root: str | None = None) -> dict[str, Any]:
    return {
        "metadata": {"generation": 1, "labels": {}},
        "spec": {"system": "fleet", "robot": "r1", "revision": "abc"},
        "status": {
            "conditions": [{"type": "Ready", "status": ready, "observedGeneration": 1}],
            **({"tree": {"rootStatus": root}} if root else {}),
        },
    }


def _drain(controller: Controller) -> set[tuple[str, str, str]]:
    pending = controller.queue.pending()
    for key in pending:
        controller.queue._due.pop(key)  # noqa: SLF001 - emptying an unstarted queue between steps
    return pending


def test_a_system_pass_is_queued_only_for_inputs_not_yet_handled() -> None:
    controller = _controller()
    system = dict(deleted=False, namespace="ns", name="fleet", uid="u1")
    controller.on_system(**system, body=_system(1))
    assert _drain(controller) == {(SYSTEM, "ns", "fleet")}
    controller.on_system(**system, body=_system(1))
    assert _drain(controller) == set(), "the echo of its own status write is not an input"
    controller.on_system(**system, body=_system(2))
    assert _drain(controller) == {(SYSTEM, "ns", "fleet")}, "a spec change is a new input"
    controller.on_system(**system, body=_system(2, {"coral.dev/rollout-undo": "abc"}))
    assert _drain(controller) == {(SYSTEM, "ns", "fleet")}, "`coral rollout undo` is a new input"
    controller.on_system(**{**system, "deleted": True}, body=_system(2))
    controller.on_system(**system, body=_system(2))
    assert _drain(controller) == {(SYSTEM, "ns", "fleet")}, "a system made again starts afresh"


def test_an_instance_change_queues_its_system_only_when_the_system_reads_it() -> None:
    controller = _controller()
    instance = dict(deleted=False, namespace="ns", name="fleet-r1", uid="i1")
    controller.on_instance(**instance, body=_instance())
    assert _drain(controller) == {(INSTANCE, "ns", "fleet-r1"), (SYSTEM, "ns", "fleet")}
    controller.on_instance(**instance, body=_instance())
    assert _drain(controller) == {(INSTANCE, "ns", "fleet-r1")}, "the system reads nothing new"
    controller.on_instance(**instance, body=_instance(ready="True"))
    assert _drain(controller) == {(INSTANCE, "ns", "fleet-r1"), (SYSTEM, "ns", "fleet")}
    controller.on_instance(**instance, body=_instance(ready="True", root="RUNNING"))
    assert (SYSTEM, "ns", "fleet") in _drain(controller), "a tree's root status gates rollouts"


def test_the_echo_of_its_own_status_write_costs_an_instance_no_pass() -> None:
    controller = _controller()
    instance = dict(deleted=False, namespace="ns", name="fleet-r1", uid="i1")
    written = {**_instance(), "metadata": {"generation": 1, "labels": {}, "resourceVersion": "7"}}
    controller.memory.statuses.remember("i1", "7", written["status"])
    controller.on_instance(**instance, body=written)
    assert (INSTANCE, "ns", "fleet-r1") not in _drain(controller), "the pass that wrote it saw it all"
    changed = {**written, "metadata": {**written["metadata"], "resourceVersion": "8"}}
    controller.on_instance(**instance, body=changed)
    assert (INSTANCE, "ns", "fleet-r1") in _drain(controller), "someone else's change is an input"


def test_a_robot_heartbeat_queues_nothing_and_a_readiness_change_queues_its_instances() -> None:
    controller = _controller()
    controller.indexes.attach(
        coral_instances={instances_on_node("n1"): [("ns", "fleet-r1")]}, coral_systems={("ns", "fleet"): []}
    )
    labels = {"coral.dev/robot": "r1"}

    def node(ready: str, heartbeat: str) -> dict[str, Any]:
        return {"conditions": [{"type": "Ready", "status": ready, "lastHeartbeatTime": heartbeat}]}

    controller.on_robot_node(
        deleted=False, name="n1", labels=labels, spec={}, status=node("True", "2026-01-01T00:00:01Z")
    )
    assert _drain(controller) == {(INSTANCE, "ns", "fleet-r1"), (SYSTEM, "ns", "fleet")}
    controller.on_robot_node(
        deleted=False, name="n1", labels=labels, spec={}, status=node("True", "2026-01-01T00:00:11Z")
    )
    assert _drain(controller) == set()
    controller.on_robot_node(
        deleted=False, name="n1", labels=labels, spec={}, status=node("False", "2026-01-01T00:00:21Z")
    )
    assert _drain(controller) == {(INSTANCE, "ns", "fleet-r1"), (SYSTEM, "ns", "fleet")}


def test_a_failed_pass_is_retried_from_the_queue() -> None:
    """The failure is simulated (a pass that raises once): the queue, not a timer, runs it again."""
    controller = _controller()
    passes: list[tuple[str, str]] = []
    done = threading.Event()

    def flaky(key: tuple[str, str]) -> None:
        passes.append(key)
        if len(passes) == 1:
            raise RuntimeError("API unavailable")
        done.set()

    controller.systems.reconcile = flaky  # type: ignore[method-assign]
    controller.queue._retry_base = 0.05  # noqa: SLF001 - a short backoff keeps the test quick
    controller.on_system(deleted=False, namespace="ns", name="fleet", uid="u1", body=_system(1))
    controller.start()
    try:
        assert done.wait(5.0), "the failed pass was not retried"
    finally:
        controller.stop()
    assert passes == [("ns", "fleet"), ("ns", "fleet")]


def test_the_operator_registers_no_change_handlers_so_it_needs_no_diff_base() -> None:
    """The settings skip kopf's per-event essence; that is right only while no handler compares one."""
    import kopf
    from coral_operator import handlers  # noqa: F401  (registers every handler)
    from coral_operator.handlers.settings import EssenceFreeDiffBase

    registry = kopf.get_default_registry()
    assert list(registry._changing.get_all_handlers()) == []
    assert list(registry._watching.get_all_handlers()), "the event handlers are registered"
    assert EssenceFreeDiffBase(prefix="coral.dev").build(body=kopf.Body({"spec": {"a": 1}})) == {}


def test_the_echo_of_its_own_status_write_queues_no_system_pass_either() -> None:
    """The pass that wrote a verdict woke the system itself (`InstanceReconciler.wake_system`)."""
    controller = _controller()
    instance = dict(deleted=False, namespace="ns", name="fleet-r1", uid="i1")
    controller.on_instance(**instance, body=_instance())
    _drain(controller)
    ready = _instance(ready="True")
    controller.memory.statuses.remember("i1", "7", ready["status"])
    controller.on_instance(
        **instance, body={**ready, "metadata": {**ready["metadata"], "resourceVersion": "7"}}
    )
    assert _drain(controller) == set()
    controller.on_instance(
        **instance, body={**ready, "metadata": {**ready["metadata"], "resourceVersion": "8"}}
    )
    assert _drain(controller) == {(INSTANCE, "ns", "fleet-r1")}, "a later change is another's"


def test_the_echo_of_a_move_handed_over_at_once_costs_its_instance_no_pass() -> None:
    controller = _controller()
    instance = dict(deleted=False, namespace="ns", name="fleet-r1", uid="i1")
    body = {**_instance(), "metadata": {"name": "fleet-r1", "namespace": "ns", "uid": "i1", "generation": 2}}
    answered = {**body, "metadata": {**body["metadata"], "resourceVersion": "9"}}
    controller.memory.moved.remember(observing.instance_record(answered))
    controller.on_instance(**instance, body=answered)
    assert _drain(controller) == {(SYSTEM, "ns", "fleet")}, "its system learns of it as of any instance"
    controller.on_instance(
        **instance, body={**body, "metadata": {**body["metadata"], "resourceVersion": "10"}}
    )
    assert _drain(controller) == {(INSTANCE, "ns", "fleet-r1")}


def test_a_new_instance_gets_its_first_pass_from_the_watch() -> None:
    """Its system pass created it and handed nothing over: its pass creates pods it owns, which the
    garbage collector would otherwise check with GETs while its own watch has not shown the owner."""
    controller = _controller()
    body = {**_instance(), "metadata": {"name": "fleet-r1", "namespace": "ns", "uid": "i1", "generation": 1}}
    created = {**body, "metadata": {**body["metadata"], "resourceVersion": "9"}}
    controller.on_instance(deleted=False, namespace="ns", name="fleet-r1", uid="i1", body=created)
    assert _drain(controller) == {(INSTANCE, "ns", "fleet-r1"), (SYSTEM, "ns", "fleet")}
