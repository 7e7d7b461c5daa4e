"""`spec.halt` of a CoralSystem reaches the instances of the robots it names, and nothing else
changes: not the revision, not a pod. A halted robot reads as halted on purpose (Ready, never
Stalled); a halt or a resume the executor has not acknowledged yet reads as work in progress."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from datetime import timedelta
from typing import Any

from coral_core.halt import HaltRequest
from coral_operator.api.instance import CoralInstanceSpec
from coral_operator.planning import pods, provenance, system_pass
from coral_operator.planning.instances import plan_instances
from coral_operator.status import instance_status
from operator_specs import NOW, observed_instance, plan_pass, robot, view_with_pods_running

ROBOTS = [robot("r1"), robot("r2"), robot("r3")]


def _plan(spec: dict[str, Any], before: system_pass.SystemPlan | None = None) -> system_pass.SystemPlan:
    """One system pass over robots r1-r3; after `before`, with what it created and stored."""
    return plan_pass(
        spec,
        list(ROBOTS),
        [observed_instance(m) for m in before.changes.create] if before else [],
        before.stored_after if before else [],
        name="mission",
    )


def _by_robot(manifests: list[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    return {m["spec"]["robot"]: m["spec"] for m in manifests}


def test_a_halt_reaches_only_the_robots_it_names_with_its_park_tree(
    spec_dict: Callable[..., dict[str, Any]],
) -> None:
    plan = _plan(spec_dict(halt={"robots": ["r2"], "parkTree": "GoHome", "parkTimeoutSeconds": 20}))
    specs = _by_robot(plan.changes.create)
    assert specs["r2"]["halt"] == {"parkTree": "GoHome", "parkTimeoutSeconds": 20}
    assert "halt" not in specs["r1"] and "halt" not in specs["r3"]


def test_a_halt_without_robots_halts_the_whole_fleet(spec_dict: Callable[..., dict[str, Any]]) -> None:
    plan = _plan(spec_dict(halt={}))
    assert [s.get("halt") for s in _by_robot(plan.changes.create).values()] == [
        {"parkTimeoutSeconds": 30}
    ] * 3


def test_halting_changes_neither_the_revision_nor_any_pod(spec_dict: Callable[..., dict[str, Any]]) -> None:
    running = _plan(spec_dict())
    halted = _plan(spec_dict(halt={"robots": ["r1"]}), running)
    # Only r1's instance is rewritten, only its halt differs, and the revision stays.
    (update,) = halted.changes.update
    before = next(m["spec"] for m in running.changes.create if m["spec"]["robot"] == "r1")
    assert {k: v for k, v in update["spec"].items() if k != "halt"} == before
    assert halted.rollout is not None and running.rollout is not None
    assert halted.rollout.target == running.rollout.target
    assert not halted.changes.create and not halted.changes.delete and halted.history is not None
    assert halted.history.create is None, "no new revision is stored"
    # The pods built from the halted instance are those of the running one, byte for byte.
    built = [
        pods.build_pods(
            spec=CoralInstanceSpec.model_validate(s), instance="i", namespace="ns", instance_uid="u"
        )
        for s in (before, update["spec"])
    ]
    assert built[0] == built[1]
    # ... and the instance is still one of its system's revision (not refused as foreign).
    parsed = CoralInstanceSpec.model_validate(update["spec"])
    assert provenance.evaluate_revision(parsed, running.stored_after) is None


def test_lifting_the_halt_clears_it_from_the_instances(spec_dict: Callable[..., dict[str, Any]]) -> None:
    halted = _plan(spec_dict(halt={}))
    resumed = _plan(spec_dict(), halted)
    assert sorted(m["spec"]["robot"] for m in resumed.changes.update) == ["r1", "r2", "r3"]
    assert all("halt" not in m["spec"] for m in resumed.changes.update)
    # Nothing to do once the instances say the same.
    again = plan_instances(
        resumed.changes.update,
        [observed_instance(m) for m in resumed.changes.update],
        {r.node_name for r in ROBOTS},
    )
    assert again.empty


def _halted_view(
    spec: dict[str, Any], *, asked: bool, acknowledged: bool, reported_after_start: bool = True
) -> instance_status.InstanceView:
    """Robot r1 with every pod Ready, its spec asking for a halt or not, and an executor report
    that acknowledges a halt or not (written after the executor started, or before)."""
    moment = NOW + (timedelta(minutes=1) if reported_after_start else -timedelta(minutes=1))
    stamp = moment.strftime("%Y-%m-%dT%H:%M:%SZ")
    tree: dict[str, Any] = {"rootStatus": "IDLE" if acknowledged else "RUNNING", "updatedAt": stamp}
    if acknowledged:
        tree["halted"] = {"since": stamp, "parkTree": "GoHome", "parkStatus": "SUCCESS"}
    view = view_with_pods_running(spec, tree=tree)
    halt = HaltRequest(park_tree="GoHome") if asked else None
    return dataclasses.replace(view, spec=view.spec.model_copy(update={"halt": halt}))


def _conditions(view: instance_status.InstanceView) -> dict[str, tuple[str, str]]:
    status = instance_status.build_instance_status(view, old_conditions=[], generation=2, now=NOW)
    return {c["type"]: (c["status"], c["reason"]) for c in status["conditions"]}


def test_a_halted_robot_reads_ready_and_halted_never_stalled(
    spec_dict: Callable[..., dict[str, Any]],
) -> None:
    conditions = _conditions(_halted_view(spec_dict(), asked=True, acknowledged=True))
    assert conditions["Halted"] == ("True", "HaltAcknowledged")
    assert conditions["Ready"][0] == "True"
    assert conditions["Stalled"][0] == "False" and conditions["Reconciling"][0] == "False"


def test_a_halt_on_its_way_reads_as_progress(spec_dict: Callable[..., dict[str, Any]]) -> None:
    conditions = _conditions(_halted_view(spec_dict(), asked=True, acknowledged=False))
    assert conditions["Halted"] == ("False", "HaltRequested")
    assert conditions["Ready"] == ("False", "HaltRequested")
    assert conditions["Reconciling"][0] == "True" and conditions["Stalled"][0] == "False"


def test_an_acknowledgement_from_before_the_executor_restarted_does_not_count(
    spec_dict: Callable[..., dict[str, Any]],
) -> None:
    view = _halted_view(spec_dict(), asked=True, acknowledged=True, reported_after_start=False)
    assert _conditions(view)["Halted"] == ("False", "HaltRequested")


def test_a_resume_on_its_way_reads_as_progress_and_then_the_condition_goes(
    spec_dict: Callable[..., dict[str, Any]],
) -> None:
    resuming = _conditions(_halted_view(spec_dict(), asked=False, acknowledged=True))
    assert resuming["Halted"] == ("True", "ResumeRequested")
    assert resuming["Ready"] == ("False", "ResumeRequested") and resuming["Stalled"][0] == "False"
    running = _conditions(_halted_view(spec_dict(), asked=False, acknowledged=False))
    assert "Halted" not in running and running["Ready"][0] == "True"
