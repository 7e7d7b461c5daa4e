"""Once back, a robot's offline boot is told on the CoralInstance (`status.offlineBoot`), read from
the report its agent writes on the robot's Node."""

from __future__ import annotations

import dataclasses
import json
from datetime import UTC, datetime
from typing import Any

import pytest
from coral_core import offline
from coral_operator.status import instance_status
from coral_operator.status.offline_boot import offline_boot
from operator_specs import BASE_SPEC, NOW, view_with_pods_running

BOOTED = "2026-03-01T10:00:00Z"
MADE = datetime(2026, 3, 1, 9, 0, tzinfo=UTC)
RUN = {"ticked": True, "rootStatus": "RUNNING", "tickCount": 70}


def _node(systems: dict[str, Any], booted: str = BOOTED) -> dict[str, str]:
    return {offline.ANNOTATION_NODE_REPORT: json.dumps({"bootedAt": booted, "systems": systems})}


def _told(annotations: dict[str, str], *, offline_on: bool = True, created: datetime | None = MADE) -> Any:
    return offline_boot(annotations, namespace="ns", system="sys", offline_on=offline_on, created=created)


def test_a_run_offline_tells_the_revision_when_it_ran_and_how_far_its_tree_got() -> None:
    handed = "2026-03-01T10:05:00Z"
    entry = {"action": "RunOffline", "revision": "abc", "handedOverAt": handed, "run": RUN}
    told = _told(_node({"ns_sys": entry}))
    assert told["outcome"] == "RanOffline"
    assert (told["bootedAt"], told["handedOverAt"], told["revision"]) == (BOOTED, handed, "abc")
    assert "ran revision abc offline" in told["message"] and "RUNNING at tick 70" in told["message"]


def test_a_refused_revision_tells_why() -> None:
    entry = {"action": "Refused", "revision": "abc", "reason": "file executor/config/tree.xml was altered"}
    told = _told(_node({"ns_sys": entry}))
    assert (told["outcome"], told["reason"]) == ("Refused", entry["reason"])
    assert "refused to run the stored revision offline: file executor/config/tree.xml" in told["message"]


@pytest.mark.parametrize(
    "systems",
    [{"": {"action": "NoRevision"}}, {"ns_other": {"action": "RunOffline", "revision": "x"}}],
    ids=["a robot with nothing stored", "a robot that stored only another system"],
)
def test_a_robot_without_a_revision_of_the_system_says_it_ran_nothing(systems: dict[str, Any]) -> None:
    told = _told(_node(systems))
    assert told["outcome"] == "NoRevision" and "ran nothing offline" in told["message"]
    assert "revision" not in told


@pytest.mark.parametrize(
    ("annotations", "offline_on", "created"),
    [
        ({}, True, MADE),
        (_node({"ns_sys": {"action": "RunOffline"}}), False, MADE),
        (_node({"ns_sys": {"action": "RunOffline"}}), True, datetime(2026, 3, 1, 11, 0, tzinfo=UTC)),
        (_node({"ns_sys": {"action": "Online"}}), True, MADE),
        (_node({"ns_sys": {"action": "RunOffline"}}, booted="yesterday"), True, MADE),
        ({offline.ANNOTATION_NODE_REPORT: "{not json"}, True, MADE),
        ({offline.ANNOTATION_NODE_REPORT: '{"systems": []}'}, True, MADE),
    ],
    ids=[
        "no report on the Node",
        "a system that does not run offline",
        "an instance made after the boot",
        "an online boot",
        "a boot time that is no time",
        "a report that is not JSON",
        "a report without its systems",
    ],
)
def test_nothing_is_told(annotations: dict[str, str], offline_on: bool, created: datetime) -> None:
    assert _told(annotations, offline_on=offline_on, created=created) is None


def test_a_run_summary_not_shaped_like_one_is_not_read() -> None:
    told = _told(_node({"ns_sys": {"action": "RunOffline", "revision": "abc", "run": "ticked"}}))
    assert "its tree never ticked" in told["message"]


def test_the_instance_status_carries_it_and_clears_it() -> None:
    told = _told(_node({"ns_sys": {"action": "RunOffline", "revision": "abc", "run": RUN}}))
    view = dataclasses.replace(view_with_pods_running(BASE_SPEC), offline_boot=told)
    status = instance_status.build_instance_status(view, old_conditions=[], generation=1, now=NOW)
    assert status["offlineBoot"] == told
    cleared = instance_status.build_instance_status(
        view_with_pods_running(BASE_SPEC), old_conditions=[], generation=1, now=NOW
    )
    # None in a merge patch removes the field.
    assert "offlineBoot" in cleared and cleared["offlineBoot"] is None
