"""The CoralInstance of a robot whose pre-pull fails says why, in the kubelet's words (`ImagesPrePulled`).

The condition exists only while the robot has a pre-pull pod, so instances of systems without
`spec.rollout.prePull` keep exactly the conditions they had.
"""

from __future__ import annotations

import dataclasses
from typing import Any

from coral_operator.status import instance_status
from operator_specs import BASE_SPEC, NOW, view_with_pods_running

NO_SPACE = "container image-0: ErrImagePull: failed to pull: no space left on device"


def _conditions(view: instance_status.InstanceView) -> dict[str, dict[str, Any]]:
    status = instance_status.build_instance_status(view, old_conditions=[], generation=1, now=NOW)
    return {c["type"]: c for c in status["conditions"]}


def test_a_failed_pull_is_named_with_the_kubelets_message_and_the_robot_keeps_running() -> None:
    view = dataclasses.replace(view_with_pods_running(BASE_SPEC), pre_pull=("rev2", NO_SPACE))
    conditions = _conditions(view)
    told = conditions["ImagesPrePulled"]
    assert (told["status"], told["reason"]) == ("False", "ImagePullFailed")
    assert "revision rev2" in told["message"] and NO_SPACE in told["message"]
    assert "stays on its revision" in told["message"]
    assert conditions["Ready"]["status"] == "True", "the old revision still runs"


def test_a_pull_under_way_is_not_a_problem() -> None:
    view = dataclasses.replace(view_with_pods_running(BASE_SPEC), pre_pull=("rev2", None))
    assert _conditions(view)["ImagesPrePulled"]["status"] == "True"


def test_without_a_pre_pull_pod_there_is_no_such_condition() -> None:
    assert "ImagesPrePulled" not in _conditions(view_with_pods_running(BASE_SPEC))
