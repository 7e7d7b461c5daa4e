"""A CoralSystem gets one CoralInstance per matching robot; spec changes and robots leaving are planned."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

from coral_operator.api.common import LabelSelector
from coral_operator.api.system import CoralSystemSpec
from coral_operator.planning import instances, selection
from coral_operator.planning.observed import ObservedInstance
from operator_specs import observed_instance, robot


def _desired(spec: dict[str, Any], robots: list[Any]) -> list[dict[str, Any]]:
    template = instances.build_template(CoralSystemSpec.model_validate(spec), "t", "p")
    return [
        instances.build_instance(system="sys", namespace="ns", system_uid="uid", robot=r, template=template)
        for r in robots
    ]


def _as_the_api_server_renders_it(manifest: dict[str, Any]) -> ObservedInstance:
    """The instance of `manifest` as read back: the API server gives `tickRateHz: 10.0` as 10."""
    spec = manifest["spec"]
    stored = {**spec, "tree": {**spec["tree"], "tickRateHz": 10}}
    return dataclasses.replace(observed_instance(manifest), spec=stored, revision="x")


def test_the_selector_matches_robots_by_labels_and_expressions() -> None:
    nodes = [robot("r1", model="x1"), robot("r2", model="x2"), robot("r3")]
    chosen = selection.select_robots(
        LabelSelector.model_validate(
            {
                "matchLabels": {"fleet": "a"},
                "matchExpressions": [{"key": "model", "operator": "In", "values": ["x1", "x2"]}],
            }
        ),
        nodes,
    )
    assert [r.robot for r in chosen] == ["r1", "r2"]
    absent = LabelSelector.model_validate(
        {"matchExpressions": [{"key": "model", "operator": "DoesNotExist"}]}
    )
    assert [r.robot for r in selection.select_robots(absent, nodes)] == ["r3"]


def test_an_empty_selector_matches_nothing() -> None:
    assert selection.select_robots(LabelSelector(), [robot("r1")]) == []


def test_one_instance_per_robot_owned_by_the_system(spec_dict: Callable[..., dict[str, Any]]) -> None:
    desired = _desired(spec_dict(), [robot("r1"), robot("r2")])
    plan = instances.plan_instances(desired, [])
    assert [m["metadata"]["name"] for m in plan.create] == ["sys-r1", "sys-r2"]
    owner = plan.create[0]["metadata"]["ownerReferences"][0]
    assert (owner["kind"], owner["name"], owner["controller"]) == ("CoralSystem", "sys", True)
    assert plan.create[0]["spec"]["nodeName"] == "r1"


def test_nothing_to_do_when_instances_match(spec_dict: Callable[..., dict[str, Any]]) -> None:
    desired = _desired(spec_dict(), [robot("r1")])
    assert instances.plan_instances(desired, [observed_instance(m) for m in desired]).empty


def test_a_spec_change_updates_every_instance_to_a_new_revision(
    spec_dict: Callable[..., dict[str, Any]],
) -> None:
    old = _desired(spec_dict(), [robot("r1")])
    new = _desired(spec_dict(ros={"domainId": 7}), [robot("r1")])
    plan = instances.plan_instances(new, [observed_instance(m) for m in old])
    assert [m["spec"]["revision"] for m in plan.update] == [new[0]["spec"]["revision"]]
    assert new[0]["spec"]["revision"] != old[0]["spec"]["revision"]


def test_the_revision_ignores_which_robots_are_selected(spec_dict: Callable[..., dict[str, Any]]) -> None:
    one = _desired(spec_dict(), [robot("r1")])[0]["spec"]["revision"]
    other = _desired(spec_dict(robots={"matchLabels": {"fleet": "b"}}), [robot("r1")])[0]["spec"]["revision"]
    assert one == other


def test_a_reachable_robot_leaving_the_selector_retires_its_instance(
    spec_dict: Callable[..., dict[str, Any]],
) -> None:
    before = _desired(spec_dict(), [robot("r1"), robot("r2")])
    after = _desired(spec_dict(), [robot("r1")])
    plan = instances.plan_instances(after, [observed_instance(m) for m in before], {"r1", "r2"})
    assert plan.retire == ["sys-r2"] and not plan.delete and not plan.create and not plan.update
    retiring = [observed_instance(m) for m in before]
    retiring[1].spec["retiring"] = True
    assert instances.plan_instances(after, retiring, {"r1", "r2"}).empty


def test_an_unreachable_or_vanished_robot_leaving_loses_its_instance_at_once(
    spec_dict: Callable[..., dict[str, Any]],
) -> None:
    before = _desired(spec_dict(), [robot("r1"), robot("r2")])
    after = _desired(spec_dict(), [robot("r1")])
    plan = instances.plan_instances(after, [observed_instance(m) for m in before], {"r1"})
    assert plan.delete == ["sys-r2"] and not plan.retire


def test_a_robot_coming_back_while_retiring_is_restored(spec_dict: Callable[..., dict[str, Any]]) -> None:
    desired = _desired(spec_dict(), [robot("r1")])
    retiring = observed_instance(desired[0])
    retiring.spec["retiring"] = True
    plan = instances.plan_instances(desired, [retiring], {"r1"})
    assert [m["metadata"]["name"] for m in plan.update] == ["sys-r1"]
    assert plan.update[0]["spec"]["retiring"] is False


def test_the_api_servers_rendering_of_the_spec_is_not_a_change(
    spec_dict: Callable[..., dict[str, Any]],
) -> None:
    desired = _desired(spec_dict(), [robot("r1")])
    observed = _as_the_api_server_renders_it(desired[0])
    assert instances.plan_instances(desired, [observed]).empty


def _built(spec: dict[str, Any], robots: list[Any]) -> tuple[list[dict[str, Any]], dict[str, str]]:
    """Manifests and their shared-spec keys, as a system pass builds them."""
    template = instances.build_template(CoralSystemSpec.model_validate(spec), "t", "p")
    builder = instances.InstanceBuilder(system="sys", namespace="ns", system_uid="uid")
    return [builder.build(r, template) for r in robots], builder.shared_keys


def test_with_shared_keys_matching_instances_are_left_alone(spec_dict: Callable[..., dict[str, Any]]) -> None:
    desired, keys = _built(spec_dict(), [robot("r1"), robot("r2")])
    assert len(set(keys.values())) == 1, "every robot at one revision shares one key"
    assert instances.plan_instances(desired, [observed_instance(m) for m in desired], None, keys).empty


def test_with_shared_keys_a_hand_edited_spec_is_still_put_back(
    spec_dict: Callable[..., dict[str, Any]],
) -> None:
    desired, keys = _built(spec_dict(), [robot("r1"), robot("r2")])
    edited = [observed_instance(m) for m in desired]
    edited[0].spec["drivers"][0]["image"] = "someone/else:1"
    plan = instances.plan_instances(desired, edited, None, keys)
    assert [m["metadata"]["name"] for m in plan.update] == ["sys-r1"]


def test_with_shared_keys_a_robots_own_field_is_still_compared(
    spec_dict: Callable[..., dict[str, Any]],
) -> None:
    desired, keys = _built(spec_dict(), [robot("r1"), robot("r2")])
    moved = [observed_instance(m) for m in desired]
    moved[1].spec["nodeName"] = "elsewhere"
    moved[0].spec["revision"] = "older"
    plan = instances.plan_instances(desired, moved, None, keys)
    assert sorted(m["metadata"]["name"] for m in plan.update) == ["sys-r1", "sys-r2"]


def test_with_shared_keys_the_api_servers_rendering_is_not_a_change(
    spec_dict: Callable[..., dict[str, Any]],
) -> None:
    desired, keys = _built(spec_dict(), [robot("r1")])
    observed = _as_the_api_server_renders_it(desired[0])
    assert instances.plan_instances(desired, [observed], None, keys).empty


def test_a_whole_number_stored_without_its_fraction_gives_the_same_shared_key(
    spec_dict: Callable[..., dict[str, Any]],
) -> None:
    desired, keys = _built(spec_dict(), [robot("r1")])
    assert isinstance(desired[0]["spec"]["tree"]["tickRateHz"], float)
    stored = observed_instance(desired[0])
    stored.spec["tree"]["tickRateHz"] = int(stored.spec["tree"]["tickRateHz"])
    assert stored.shared_spec_key == keys["sys-r1"]


def test_an_instance_written_by_hand_at_a_name_of_the_system_is_taken_over(
    spec_dict: Callable[..., dict[str, Any]],
) -> None:
    """Issue 47, item 6: a CoralInstance created by hand before its robot joined had the system's
    spec but no owner; the system now writes its owner (and spec) over it."""
    desired, keys = _built(spec_dict(), [robot("r1")])
    forged = dataclasses.replace(observed_instance(desired[0]), controller_uid="")
    plan = instances.plan_instances(desired, [forged], None, keys, "uid")
    assert [m["metadata"]["ownerReferences"][0]["uid"] for m in plan.update] == ["uid"]


def test_a_leaving_instance_the_system_does_not_control_is_deleted_not_asked_to_stop(
    spec_dict: Callable[..., dict[str, Any]],
) -> None:
    desired, keys = _built(spec_dict(), [robot("r1"), robot("r2")])
    stray = dataclasses.replace(observed_instance(desired[1]), controller_uid="")
    plan = instances.plan_instances(desired[:1], [observed_instance(desired[0]), stray], {"r2"}, keys, "uid")
    assert (plan.retire, plan.delete) == ([], ["sys-r2"])
