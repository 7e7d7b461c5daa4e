"""The startup health timeout measures startup only: from a pod's creation, its loss of readiness or
its robot's return, until the component is ready; never a running or finished mission.

Issue 50: the timer counted from each pod's creation for the pod's whole life, so every mission
longer than the timeout ended with about a second of `Stalled=True` (the transient bag player's
pod unready between its exit and `Succeeded`), and a robot back from a reboot read `Stalled` until
its components were Ready again (42 s on a real robot). Each case goes from the pod bodies the
kubelet writes, through the instance pass, to the conditions kstatus reads.
"""

from __future__ import annotations

import copy
import dataclasses
from datetime import timedelta
from typing import Any

import pytest
from coral_core import names
from coral_core.instance_status import RootStatus, TreeState
from coral_operator.api.system import CoralSystemSpec
from coral_operator.kube import observing
from coral_operator.planning import instance_pass, instances
from coral_operator.planning.observed import InstanceRecord, RobotNode
from coral_operator.status import instance_status
from operator_specs import BASE_SPEC, NOW, robot

TIMEOUT_S = 120


def _at(seconds_ago: float) -> str:
    return (NOW - timedelta(seconds=seconds_ago)).strftime("%Y-%m-%dT%H:%M:%SZ")


def _record() -> InstanceRecord:
    spec = copy.deepcopy(BASE_SPEC)
    spec["drivers"] = [{"name": "lidar", "image": "example/lidar:1", "transient": True}]
    spec["startup"] = {"healthTimeoutSeconds": TIMEOUT_S, "onTimeout": "Block"}
    template = instances.build_template(CoralSystemSpec.model_validate(spec), "t", "p")
    return InstanceRecord(
        name="sys-r1",
        namespace="ns",
        uid="u",
        generation=1,
        spec=instances.build_instance_spec("sys", robot("r1"), template),
        status={},
    )


def _pod(
    manifest: dict[str, Any],
    *,
    created: float,
    state: dict[str, Any],
    ready_since: float | None = None,
    unready_since: float | None = None,
    phase: str = "Running",
    restarts: int = 0,
    last_state: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """A component pod as its kubelet reports it; times are seconds before NOW."""
    ready = ready_since is not None
    transition = ready_since if ready else unready_since
    transition = created if transition is None else transition
    container = {
        "name": manifest["spec"]["containers"][0]["name"],
        "ready": ready,
        "restartCount": restarts,
        "state": state,
        "lastState": last_state or {},
    }
    return {
        "metadata": {**manifest["metadata"], "creationTimestamp": _at(created)},
        "status": {
            "phase": phase,
            "conditions": [{"type": "Ready", "status": str(ready), "lastTransitionTime": _at(transition)}],
            "containerStatuses": [container],
        },
    }


def _running(since: float) -> dict[str, Any]:
    return {"running": {"startedAt": _at(since)}}


def _conditions(
    build: dict[str, Any], node: RobotNode | None = None, tree: RootStatus = "RUNNING"
) -> dict[str, tuple[str, str]]:
    """The instance's conditions once its pass has seen the pods `build` gives per component."""
    record = _record()
    spec = instance_pass.parse_instance_spec(record)
    assert not isinstance(spec, str), spec
    desired = instance_pass.build_desired_pods(record, spec)
    by_component = {m["metadata"]["labels"][names.LABEL_COMPONENT]: m for m in desired}
    observed = [
        pod
        for component, make in build.items()
        for pod in observing.observed_pods(make(by_component[component]))
    ]
    node = node or robot("r1")
    plan = instance_pass.plan_instance(
        record=record, spec=spec, desired=desired, node=node, observed=observed, now=NOW
    )
    assert plan.startup is not None
    view = instance_status.InstanceView(
        spec=spec,
        node=node,
        desired=desired,
        pods=observed,
        plan=plan.startup,
        transient=plan.transient,
        tree=TreeState(root_status=tree, updated_at=_at(1)),
        plugins=None,
    )
    status = instance_status.build_instance_status(view, old_conditions=[], generation=1, now=NOW)
    return {c["type"]: (c["status"], c["reason"]) for c in status["conditions"]}


def _ready(created: float) -> Any:
    return lambda m: _pod(m, created=created, state=_running(created - 1), ready_since=created - 5)


def _exited(created: float, finished: float, phase: str = "Succeeded") -> Any:
    """A pod whose container ran from its creation and exited 0 `finished` seconds ago."""
    ran = {"exitCode": 0, "startedAt": _at(created - 1), "finishedAt": _at(finished)}
    return lambda m: _pod(m, created=created, state={"terminated": ran}, unready_since=finished, phase=phase)


def _returned(node_ready_since: float) -> RobotNode:
    return dataclasses.replace(robot("r1"), ready_since=NOW - timedelta(seconds=node_ready_since))


MISSION_CASES = {
    "a long mission running": (
        {"lidar": _ready(600), "slam": _ready(590), "executor": _ready(580)},
        "RUNNING",
    ),
    "the bag player exiting at the end of a long mission (unready, not yet Succeeded)": (
        {
            "lidar": _exited(600, 0, phase="Running"),
            "slam": _ready(590),
            "executor": _ready(580),
        },
        "RUNNING",
    ),
    "a long mission finished": (
        {
            "lidar": _exited(600, 30),
            "slam": _ready(590),
            "executor": _exited(580, 2),
        },
        "SUCCESS",
    ),
    "a skillset's readiness probe missing mid-mission for longer than the timeout": (
        {
            "lidar": _ready(600),
            "slam": lambda m: _pod(m, created=590, state=_running(589), unready_since=200),
            "executor": _ready(580),
        },
        "RUNNING",
    ),
}


@pytest.mark.parametrize(("build", "tree"), MISSION_CASES.values(), ids=MISSION_CASES.keys())
def test_a_mission_longer_than_the_timeout_never_reads_stalled(build: dict[str, Any], tree: str) -> None:
    conditions = _conditions(build, tree=tree)
    assert conditions["Stalled"] == ("False", "Ready"), conditions
    assert conditions["ComponentsReady"][1] != "HealthTimeout", conditions


def test_a_robot_back_from_a_reboot_starts_its_timeout_over() -> None:
    """Power lost 10 minutes into a mission: the node-lifecycle controller turned the pods unready
    when the robot's Lease lapsed (300 s ago), and the robot turned Ready again 20 s ago; the
    driver's container is being created again, the skillset's restarted 15 s ago."""
    rebooted = {
        "lidar": lambda m: _pod(
            m,
            created=900,
            state={"waiting": {"reason": "ContainerCreating"}},
            unready_since=300,
            last_state={"terminated": {"exitCode": 255, "reason": "Unknown", "startedAt": _at(899)}},
        ),
        "slam": lambda m: _pod(m, created=890, state=_running(15), unready_since=300, restarts=1),
        "executor": lambda m: _pod(m, created=880, state=_running(14), unready_since=300, restarts=1),
    }
    conditions = _conditions(rebooted, node=_returned(20))
    assert conditions["Stalled"] == ("False", "Ready"), conditions
    assert conditions["ComponentsReady"] == ("False", "WaitingForDrivers"), conditions
    # The same robot when its driver still is not ready a full timeout after the robot came back.
    conditions = _conditions(rebooted, node=_returned(TIMEOUT_S + 10))
    assert conditions["Stalled"] == ("True", "HealthTimeout"), conditions


def test_a_component_that_crashed_mid_mission_gets_a_new_startup() -> None:
    def crashed(seconds_ago: float) -> Any:
        return lambda m: _pod(
            m, created=600, state=_running(seconds_ago - 3), unready_since=seconds_ago, restarts=1
        )

    conditions = _conditions({"lidar": crashed(30), "slam": _ready(590), "executor": _ready(580)})
    assert conditions["Stalled"] == ("False", "Ready"), conditions
    assert conditions["ComponentsReady"] == ("False", "WaitingForDrivers"), conditions
    conditions = _conditions({"lidar": crashed(TIMEOUT_S + 5), "slam": _ready(590), "executor": _ready(580)})
    assert conditions["Stalled"] == ("True", "HealthTimeout"), conditions


@pytest.mark.parametrize(
    ("age_s", "stalled"),
    [(TIMEOUT_S - 5, ("False", "Ready")), (TIMEOUT_S + 5, ("True", "HealthTimeout"))],
    ids=["within the timeout", "past the timeout"],
)
def test_a_driver_that_never_becomes_ready_is_still_reported(age_s: float, stalled: tuple[str, str]) -> None:
    """The kubelet wrote Ready=False with the pod's first status, before the container started."""
    never = {"lidar": lambda m: _pod(m, created=age_s, state=_running(age_s - 2), unready_since=age_s)}
    conditions = _conditions(never)
    assert conditions["Stalled"] == stalled, conditions
