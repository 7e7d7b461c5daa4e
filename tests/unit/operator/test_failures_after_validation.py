"""What goes wrong after validation reaches the instance in the words of whoever refused it, and
what the executor writes into the operator's part of the status counts for nothing."""

from __future__ import annotations

from typing import Any

from coral_operator.api.instance import CoralInstanceSpec
from coral_operator.api.system import CoralSystemSpec, StartupSpec
from coral_operator.kube import observing
from coral_operator.planning import instances, pods
from coral_operator.planning.observed import ObservedPod
from coral_operator.status import instance_status, ownership
from coral_operator.status.conditions import ConditionType, Reason
from coral_operator.status.transitions import MAX_MESSAGE, Verdict, merge_conditions
from operator_specs import BASE_SPEC, NOW, instance_view, robot

PSA = 'pods "x" is forbidden: violates PodSecurity "baseline:latest": hostPath volumes (volume "plugins")'


def _view(pods_seen: list[ObservedPod] | None = None, refused: dict[str, str] | None = None) -> Any:
    template = instances.build_template(CoralSystemSpec.model_validate(BASE_SPEC), "t", "p")
    spec = CoralInstanceSpec.model_validate(instances.build_instance_spec("sys", robot("r1"), template))
    desired = pods.build_pods(spec=spec, instance="sys-r1", namespace="ns", instance_uid="u")
    return instance_view(spec, desired, pods_seen or [], startup=StartupSpec(), refused=refused)


def _conditions(view: Any) -> dict[str, dict[str, Any]]:
    status = instance_status.build_instance_status(view, old_conditions=[], generation=2, now=NOW)
    return {c["type"]: c for c in status["conditions"]}


def test_a_pod_refused_by_admission_stalls_the_instance_with_the_servers_message() -> None:
    conditions = _conditions(_view(refused={"lidar": PSA}))
    assert conditions["ComponentsReady"]["reason"] == "PodRefused"
    assert conditions["Stalled"]["status"] == "True"
    assert conditions["Ready"]["status"] == "False"
    assert f"lidar: {PSA}" in conditions["Stalled"]["message"]


def _pod(body_status: dict[str, Any]) -> ObservedPod:
    template = instances.build_template(CoralSystemSpec.model_validate(BASE_SPEC), "t", "p")
    spec = CoralInstanceSpec.model_validate(instances.build_instance_spec("sys", robot("r1"), template))
    manifest = pods.build_pods(spec=spec, instance="sys-r1", namespace="ns", instance_uid="u")[0]
    return observing.observed_pod({"metadata": manifest["metadata"], "status": body_status})


def test_an_image_that_cannot_be_pulled_is_named_with_the_kubelets_message() -> None:
    pod = _pod(
        {
            "phase": "Pending",
            "containerStatuses": [
                {
                    "name": "lidar",
                    "restartCount": 0,
                    "state": {
                        "waiting": {
                            "reason": "ImagePullBackOff",
                            "message": 'Back-off pulling image "nope:1"',
                        }
                    },
                }
            ],
        }
    )
    conditions = _conditions(_view([pod]))
    assert conditions["ComponentsReady"]["reason"] == "ImagePullFailed"
    assert 'lidar: ImagePullBackOff: Back-off pulling image "nope:1"' in conditions["Ready"]["message"]
    # The kubelet keeps retrying, so the instance is not stalled: a fixed registry heals it.
    assert conditions["Stalled"]["status"] == "False"


def test_a_pod_the_robot_cannot_admit_is_named() -> None:
    pod = _pod({"phase": "Failed", "reason": "OutOfcpu", "message": "Node didn't have enough resource: cpu"})
    conditions = _conditions(_view([pod]))
    assert conditions["ComponentsReady"]["reason"] == "PodUnschedulable"
    assert "lidar: OutOfcpu: Node didn't have enough resource: cpu" in conditions["Ready"]["message"]


def test_the_operator_part_of_the_status_excludes_only_what_the_executor_reports() -> None:
    status = {
        "conditions": [{"type": "Ready"}],
        "tree": {"rootStatus": "RUNNING"},
        "plugins": {},
        "robot": {},
    }
    assert ownership.operator_part(status) == {"conditions": [{"type": "Ready"}], "robot": {}}
    assert ownership.executor_part(status) == {"tree": {"rootStatus": "RUNNING"}, "plugins": {}}


def test_a_forged_ready_is_recomputed_from_what_is_observed() -> None:
    forged = [
        {
            "type": "Ready",
            "status": "True",
            "reason": "Ready",
            "message": "forged",
            "observedGeneration": 2,
            "lastTransitionTime": "2026-01-01T00:00:00Z",
        }
    ]
    view = _view(refused={"lidar": PSA})
    status = instance_status.build_instance_status(view, old_conditions=forged, generation=2, now=NOW)
    ready = next(c for c in status["conditions"] if c["type"] == "Ready")
    assert (ready["status"], ready["reason"]) == ("False", "PodRefused")
    assert ready["lastTransitionTime"] == "2026-01-01T12:00:00Z"


def test_a_huge_message_is_cut_to_what_the_status_can_hold() -> None:
    long = "x" * 100_000
    (entry,) = merge_conditions(
        [], [Verdict(ConditionType.STALLED, True, Reason.INVALID_TREE, long)], generation=1, now=NOW
    )
    assert len(entry["message"]) <= MAX_MESSAGE and entry["message"].endswith("(100000 characters)")
