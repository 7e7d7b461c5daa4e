"""Drivers start first, skillsets when drivers are Ready, executors when skillsets are Ready."""

from __future__ import annotations

from collections.abc import Callable
from datetime import timedelta
from typing import Any

import pytest
from coral_core import names
from coral_operator.api.instance import CoralInstanceSpec
from coral_operator.api.system import CoralSystemSpec, StartupSpec
from coral_operator.planning import instances, pods, startup
from coral_operator.planning.observed import ObservedPod
from operator_specs import NOW, robot


def _desired(spec: dict[str, Any]) -> list[dict[str, Any]]:
    template = instances.build_template(CoralSystemSpec.model_validate(spec), "t", "p")
    parsed = CoralInstanceSpec.model_validate(instances.build_instance_spec("sys", robot("r1"), template))
    return pods.build_pods(spec=parsed, instance="sys-r1", namespace="ns", instance_uid="u")


def _observed(
    manifest: dict[str, Any], *, ready: bool, age_s: float = 5, phase: str = "Running", **kw: Any
) -> ObservedPod:
    labels = manifest["metadata"]["labels"]
    return ObservedPod(
        name=manifest["metadata"]["name"],
        component=labels[names.LABEL_COMPONENT],
        role=labels[names.LABEL_ROLE],
        revision=kw.pop("revision", labels[names.LABEL_REVISION]),
        pod_hash=kw.pop("pod_hash", manifest["metadata"]["annotations"][names.ANNOTATION_POD_HASH]),
        phase=phase,
        ready=ready,
        created=NOW - timedelta(seconds=age_s),
        **kw,
    )


def _plan(
    desired: list[dict[str, Any]],
    observed: list[ObservedPod],
    transient: set[str] | None = None,
    **startup_spec: Any,
) -> startup.StartupPlan:
    return startup.plan_startup(
        desired=desired,
        observed=observed,
        transient=transient or set(),
        startup=StartupSpec(**startup_spec),
        now=NOW,
    )


def _components(manifests: list[dict[str, Any]]) -> list[str]:
    return [m["metadata"]["labels"][names.LABEL_COMPONENT] for m in manifests]


def test_a_new_robot_starts_with_its_drivers_only(spec_dict: Callable[..., dict[str, Any]]) -> None:
    plan = _plan(_desired(spec_dict()), [])
    assert _components(plan.create) == ["lidar"]
    assert plan.waiting_for == "driver"


def test_skillsets_wait_for_a_driver_that_is_running_but_not_ready(
    spec_dict: Callable[..., dict[str, Any]],
) -> None:
    desired = _desired(spec_dict())
    plan = _plan(desired, [_observed(desired[0], ready=False)])
    assert plan.create == []
    assert "lidar" in plan.message


def test_skillsets_start_once_the_drivers_are_ready(spec_dict: Callable[..., dict[str, Any]]) -> None:
    desired = _desired(spec_dict())
    plan = _plan(desired, [_observed(desired[0], ready=True)])
    assert _components(plan.create) == ["slam"]
    assert plan.waiting_for == "skillset"


def test_executors_start_once_the_skillsets_are_ready(spec_dict: Callable[..., dict[str, Any]]) -> None:
    desired = _desired(spec_dict())
    plan = _plan(desired, [_observed(desired[0], ready=True), _observed(desired[1], ready=True)])
    assert _components(plan.create) == ["executor"]
    assert plan.waiting_for is None


def test_a_transient_driver_that_succeeded_counts_as_done(spec_dict: Callable[..., dict[str, Any]]) -> None:
    desired = _desired(spec_dict(drivers=[{"name": "lidar", "image": "l", "transient": True}]))
    plan = _plan(desired, [_observed(desired[0], ready=False, phase="Succeeded")], transient={"lidar"})
    assert _components(plan.create) == ["slam"]


def test_a_stage_without_components_does_not_block(spec_dict: Callable[..., dict[str, Any]]) -> None:
    plan = _plan(_desired(spec_dict(drivers=[])), [])
    assert _components(plan.create) == ["slam"]


@pytest.mark.parametrize(
    ("on_timeout", "age_s", "created", "timed_out"),
    [
        ("Block", 10, [], False),
        ("Block", 200, [], True),
        ("Proceed", 10, [], False),
        ("Proceed", 200, ["slam"], True),
    ],
    ids=["block within timeout", "block after timeout", "proceed within timeout", "proceed after timeout"],
)
def test_a_driver_that_never_becomes_ready(
    spec_dict: Callable[..., dict[str, Any]],
    on_timeout: str,
    age_s: float,
    created: list[str],
    timed_out: bool,
) -> None:
    desired = _desired(spec_dict())
    plan = _plan(
        desired,
        [_observed(desired[0], ready=False, age_s=age_s)],
        healthTimeoutSeconds=120,
        onTimeout=on_timeout,
    )
    assert _components(plan.create) == created
    assert plan.timed_out is timed_out
    if timed_out:
        assert f"onTimeout={on_timeout}" in plan.message


def test_a_changed_component_is_deleted_then_recreated_when_gone(
    spec_dict: Callable[..., dict[str, Any]],
) -> None:
    before = _desired(spec_dict())
    desired = _desired(spec_dict(executors=[{"name": "executor", "image": "example/executor:2"}]))
    kept = [_observed(m, ready=True) for m in desired[:2]]
    old = _observed(before[2], ready=True)
    plan = _plan(desired, [*kept, old])
    assert plan.delete == [old.name] and plan.create == []
    # The replacement has another name, so only the component label can say the old pod is in its way.
    terminating = _observed(before[2], ready=True, deleting=True)
    plan = _plan(desired, [*kept, terminating])
    assert plan.delete == [] and plan.create == []
    plan = _plan(desired, kept)
    assert plan.create == [desired[2]]
    assert plan.create[0]["metadata"]["name"] != old.name


def test_the_pods_of_a_replaced_revision_go_in_one_request(spec_dict: Callable[..., dict[str, Any]]) -> None:
    env = [{"name": "MODE", "value": "2"}]
    old = [_observed(m, ready=True, revision="older") for m in _desired(spec_dict())]
    changed = {
        "drivers": [{"name": "lidar", "image": "example/lidar:1", "env": env}],
        "skillsets": [{"name": "slam", "image": "example/slam:1", "env": env}],
    }
    plan = _plan(_desired(spec_dict(**changed)), old)
    assert sorted(plan.delete) == sorted(p.name for p in old[:2])
    # The executor did not change and is relabelled: a selector on the old revision would take it too.
    assert plan.delete_selector is None
    everything = _desired(
        spec_dict(**changed, executors=[{"name": "executor", "image": "example/executor:2", "env": env}])
    )
    plan = _plan(everything, old)
    assert sorted(plan.delete) == sorted(p.name for p in old)
    assert plan.delete_selector == {
        names.LABEL_INSTANCE: "sys-r1",
        names.LABEL_REVISION: "older",
        names.LABEL_MANAGED_BY: names.MANAGER,
    }
    one = _plan(everything, old[:1])
    assert one.delete == [old[0].name] and one.delete_selector is None, "one pod is deleted by name"


def test_a_changed_driver_never_runs_beside_its_replacement(
    spec_dict: Callable[..., dict[str, Any]],
) -> None:
    before = _desired(spec_dict())
    desired = _desired(spec_dict(drivers=[{"name": "lidar", "image": "example/lidar:2"}]))
    terminating = _observed(before[0], ready=True, deleting=True)
    plan = _plan(desired, [terminating])
    assert plan.create == [] and plan.delete == []
    assert plan.waiting_for == "driver" and plan.wake_at is None
    assert _components(_plan(desired, []).create) == ["lidar"]


def test_a_deleted_current_pod_comes_back_only_once_it_is_gone(
    spec_dict: Callable[..., dict[str, Any]],
) -> None:
    desired = _desired(spec_dict())
    plan = _plan(desired, [_observed(desired[0], ready=True, deleting=True)])
    assert plan.create == [] and plan.delete == []
    assert _components(_plan(desired, []).create) == ["lidar"]


def test_a_current_pod_is_found_by_component_and_hash_not_by_name(
    spec_dict: Callable[..., dict[str, Any]],
) -> None:
    desired = _desired(spec_dict())
    # Same content under another name, as pods named before names carried the hash.
    renamed = [
        ObservedPod(**{**_observed(m, ready=True, revision="older").__dict__, "name": f"legacy-{i}"})
        for i, m in enumerate(desired)
    ]
    plan = _plan(desired, renamed)
    assert (plan.create, plan.delete, plan.waiting_for) == ([], [], None)
    assert [name for name, _ in plan.relabel] == ["legacy-0", "legacy-1", "legacy-2"]


def test_an_unchanged_pod_of_a_new_revision_is_relabelled_not_restarted(
    spec_dict: Callable[..., dict[str, Any]],
) -> None:
    desired = _desired(spec_dict())
    observed = [_observed(m, ready=True, revision="older") for m in desired]
    plan = _plan(desired, observed)
    assert plan.delete == [] and plan.create == []
    assert [name for name, _ in plan.relabel] == [p.name for p in observed]


def test_a_removed_component_loses_its_pod(spec_dict: Callable[..., dict[str, Any]]) -> None:
    desired = _desired(spec_dict())
    extra = _observed(desired[1], ready=True)
    orphan = ObservedPod(**{**extra.__dict__, "name": "sys-r1-old", "component": "old"})
    plan = _plan(desired, [*(_observed(m, ready=True) for m in desired), orphan])
    assert plan.delete == ["sys-r1-old"]


def test_a_running_system_needs_nothing(spec_dict: Callable[..., dict[str, Any]]) -> None:
    desired = _desired(spec_dict())
    plan = _plan(desired, [_observed(m, ready=True) for m in desired])
    assert (plan.create, plan.delete, plan.relabel, plan.waiting_for) == ([], [], [], None)


def test_a_retiring_robot_stops_executors_then_skillsets_then_drivers(
    spec_dict: Callable[..., dict[str, Any]],
) -> None:
    desired = _desired(spec_dict())
    running = [_observed(m, ready=True) for m in desired]
    names = [p.name for p in running]
    assert startup.plan_shutdown(running) == [names[2]]
    terminating = _observed(desired[2], ready=True, deleting=True)
    assert startup.plan_shutdown([*running[:2], terminating]) == []
    assert startup.plan_shutdown(running[:2]) == [names[1]]
    assert startup.plan_shutdown(running[:1]) == [names[0]]
    assert startup.plan_shutdown([]) == []


def test_a_waiting_stage_asks_to_be_planned_again_when_its_timeout_falls_due(
    spec_dict: Callable[..., dict[str, Any]],
) -> None:
    desired = _desired(spec_dict())
    plan = _plan(desired, [_observed(desired[0], ready=False, age_s=30)], healthTimeoutSeconds=120)
    assert plan.wake_at == NOW + timedelta(seconds=90)
    assert (
        _plan(desired, [_observed(desired[0], ready=False, age_s=300)], healthTimeoutSeconds=120).wake_at
        is None
    )
