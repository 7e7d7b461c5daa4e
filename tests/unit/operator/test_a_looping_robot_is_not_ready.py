"""A robot whose executor reports that its tree makes no progress is not Ready, and says where.

Issue 50: a robot retried `ProcessScan` 240,000 times in ten minutes while its CoralInstance read
`Ready`, `LibrariesHealthy`, `TreeOk`, RUNNING. The executor reports such a loop in
`status.tree.noProgress` (`coral.executor.progress`); the operator turns it into `TreeHealthy`
and `Ready` False, reason `NoProgress`, not `Stalled`: the loop may end by itself.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from coral_operator.api.instance import CoralInstanceSpec
from coral_operator.api.system import CoralSystemSpec
from coral_operator.planning import instances, pods
from coral_operator.status import executor_report, instance_status
from operator_specs import NOW, robot, view_with_pods_running

LOOP = {
    "path": "Main/IterateSLAM/ProcessScan",
    "message": "localization is disabled",
    "since": "2026-01-01T11:50:00Z",
}


def _conditions(view: instance_status.InstanceView) -> dict[str, dict[str, Any]]:
    status = instance_status.build_instance_status(view, old_conditions=[], generation=1, now=NOW)
    return {c["type"]: c for c in status["conditions"]}


def test_a_tree_that_makes_no_progress_is_not_ready_and_names_the_node(
    spec_dict: Callable[..., dict[str, Any]],
) -> None:
    conditions = _conditions(
        view_with_pods_running(spec_dict(), tree={"rootStatus": "RUNNING", "noProgress": LOOP})
    )
    tree = conditions["TreeHealthy"]
    assert (tree["status"], tree["reason"]) == ("False", "NoProgress")
    assert "Main/IterateSLAM/ProcessScan" in tree["message"] and "localization is disabled" in tree["message"]
    assert "2026-01-01T11:50:00Z" in tree["message"]
    assert (conditions["Ready"]["status"], conditions["Ready"]["reason"]) == ("False", "NoProgress")
    assert conditions["Stalled"]["status"] == "False", "the loop may end by itself"
    assert conditions["Reconciling"]["message"] == conditions["Ready"]["message"], "not 'components ready'"


def test_the_loop_ending_makes_the_robot_ready_again(spec_dict: Callable[..., dict[str, Any]]) -> None:
    conditions = _conditions(view_with_pods_running(spec_dict(), tree={"rootStatus": "RUNNING"}))
    assert (conditions["Ready"]["status"], conditions["TreeHealthy"]["reason"]) == ("True", "TreeOk")


def test_a_no_progress_report_that_is_no_object_is_ignored_and_named() -> None:
    report = executor_report.read_executor_report({"tree": {"rootStatus": "RUNNING", "noProgress": "forged"}})
    assert report.tree is not None and report.tree.to_patch() == {"rootStatus": "RUNNING"}
    assert report.ignored_tree == [
        "status.tree.noProgress: 'forged' is not an object of path, message and RFC 3339 time"
    ]


def _executor_command(spec: dict[str, Any]) -> list[str]:
    template = instances.build_template(CoralSystemSpec.model_validate(spec), "t", "p")
    parsed = CoralInstanceSpec.model_validate(instances.build_instance_spec("sys", robot("r1"), template))
    desired = pods.build_pods(spec=parsed, instance="sys-r1", namespace="ns", instance_uid="u")
    return desired[-1]["spec"]["containers"][0]["command"]


def test_the_time_a_node_may_loop_reaches_the_executor_only_when_set(
    spec_dict: Callable[..., dict[str, Any]],
) -> None:
    default, loose = spec_dict(), spec_dict()
    loose["tree"] = {**loose["tree"], "noProgressSeconds": 300}
    assert "--no-progress" not in _executor_command(default), (
        "pods of systems that leave it out keep their hash"
    )
    command = _executor_command(loose)
    assert command[command.index("--no-progress") + 1] == "300"
    template = instances.build_template(CoralSystemSpec.model_validate(default), "t", "p")
    assert "noProgressSeconds" not in template["tree"], "nor their revision"
