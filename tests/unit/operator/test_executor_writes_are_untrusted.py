"""Whatever an executor writes into its CoralInstance's status, the operator's pass still writes its own.

Issue 47, item 5: with its own token an executor wrote `Ready=True` and a `status.tree.updatedAt`
that is no time. Every pass of that instance then raised while reading the time, before writing
its conditions, so the forged Ready stuck and `kubectl wait` succeeded while nothing ran. Here any
value in any field the executor can reach (its own `tree` and `plugins`, and the operator's
fields it may overwrite) is fed to the status computation: it never raises, Ready never turns
True from it, and an unreadable field of the executor's is named on the conditions.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest
from coral_operator.api import keys
from coral_operator.kube import observing
from coral_operator.planning import status_pacing
from coral_operator.status import executor_report, instance_status, transitions
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from operator_specs import BASE_SPEC, NOW, view_with_pods_running

TIMES = ["2026-01-01T12:00:00Z", "2026-01-01", "yesterday", "2026-13-45T99:00:00Z", "", "9" * 40]
SCALARS = (
    st.none()
    | st.booleans()
    | st.integers(min_value=-(2**70), max_value=2**70)
    | st.floats(allow_nan=True)
    | st.text(max_size=12)
    | st.sampled_from([*TIMES, "FAILURE", "RUNNING", "SUCCESS", "Ready", "True"])
)
FIELD_NAMES = [
    *keys.TREE,
    *keys.PLUGINS,
    *keys.TREE_FAILURE,
    *keys.CONDITION,
    *keys.ROBOT,
    *keys.INSTANCE_STATUS,
]
JUNK = st.recursive(
    SCALARS,
    lambda inner: (
        st.lists(inner, max_size=4)
        | st.dictionaries(st.sampled_from(FIELD_NAMES) | st.text(max_size=6), inner, max_size=5)
    ),
    max_leaves=12,
)


def _shaped(fields: Any) -> st.SearchStrategy[Any]:
    """Objects with the model's field names holding anything, or anything at all."""
    return st.fixed_dictionaries({}, optional={name: JUNK for name in fields}) | JUNK


FORGED_READY = {
    "type": "Ready",
    "status": "True",
    "reason": "Ready",
    "message": "forged",
    "observedGeneration": 3,
    "lastTransitionTime": "2026-01-01T00:00:00Z",
}
CONDITIONS = (
    st.lists(
        st.just(FORGED_READY) | _shaped(keys.CONDITION),
        max_size=4,
    )
    | JUNK
)
STATUSES = st.fixed_dictionaries(
    {},
    optional={
        keys.INSTANCE_STATUS.tree: _shaped(keys.TREE)
        | st.fixed_dictionaries(
            {keys.TREE.root_status: st.sampled_from(["RUNNING", "FAILURE"])},
            optional={
                keys.TREE.updated_at: st.sampled_from(TIMES),
                keys.TREE.last_failure: _shaped(keys.TREE_FAILURE),
            },
        ),
        keys.INSTANCE_STATUS.plugins: _shaped(keys.PLUGINS),
        keys.INSTANCE_STATUS.conditions: CONDITIONS,
        keys.INSTANCE_STATUS.observed_generation: JUNK,
        keys.INSTANCE_STATUS.robot: _shaped(keys.ROBOT),
    },
)


def _view(status: dict[str, Any], *, ready: bool) -> instance_status.InstanceView:
    """Robot r1 with every component's pod up, Ready or not, and the executor's report read from
    `status` as the reconciler reads it."""
    report = executor_report.read_executor_report(status)
    view = view_with_pods_running(BASE_SPEC, ready=ready, tree=report.tree, plugins=report.plugins)
    return instance_status.InstanceView(
        **{**view.__dict__, "ignored_tree": report.ignored_tree, "ignored_plugins": report.ignored_plugins}
    )


def _status_pass(status: dict[str, Any], *, ready: bool) -> dict[str, Any]:
    """Everything a pass computes from the status it read, as `reconcile.instances` does it."""
    new = instance_status.build_instance_status(
        _view(status, ready=ready),
        old_conditions=transitions.written_conditions(status),
        generation=3,
        now=NOW,
    )
    status_pacing.verdict_of(status)
    status_pacing.stale_status_says_as_much(status, new, 3)
    status_pacing.pending_status_says_as_much(status, new)
    observed = observing.observed_instance({"metadata": {"generation": 3}, "spec": {}, "status": status})
    assert observed.root_status in (None, *executor_report.ROOT_STATUSES)
    return new


def _ready(status: dict[str, Any]) -> str:
    return next(c for c in status["conditions"] if c["type"] == "Ready")["status"]


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(status=STATUSES)
def test_anything_the_executor_writes_never_stops_the_pass_nor_makes_the_robot_ready(
    status: dict[str, Any],
) -> None:
    assert _ready(_status_pass(status, ready=False)) == "False"
    # With every pod Ready, the executor's report can take Ready away (a failed tree), never give it.
    if _ready(_status_pass(status, ready=True)) == "True":
        assert _ready(_status_pass({}, ready=True)) == "True"


@pytest.mark.parametrize(
    ("status", "field"),
    [
        ({"tree": {"rootStatus": "RUNNING", "updatedAt": "yesterday"}}, "status.tree.updatedAt"),
        ({"tree": {"rootStatus": "RUNNING", "updatedAt": "2026-01-01"}}, "status.tree.updatedAt"),
        ({"tree": {"rootStatus": "EXPLODED"}}, "status.tree.rootStatus"),
        ({"tree": {"rootStatus": "FAILURE", "lastFailure": "here"}}, "status.tree.lastFailure"),
        ({"tree": "RUNNING"}, "status.tree"),
        ({"plugins": {"missing": "Nav"}}, "status.plugins.missing"),
        ({"plugins": {"degraded": [1, 2]}}, "status.plugins.degraded"),
    ],
)
def test_an_unreadable_field_of_the_executors_is_named_on_its_condition(
    status: dict[str, Any], field: str
) -> None:
    conditions = {c["type"]: c for c in _status_pass(status, ready=True)["conditions"]}
    where = "PluginsReady" if field.startswith("status.plugins") else "TreeHealthy"
    assert f"Ignored what the executor wrote: {field}:" in conditions[where]["message"]


def test_a_forged_ready_with_an_unparsable_time_is_overwritten_in_one_pass() -> None:
    """The attack of item 5 exactly: the pods are not Ready, the executor says Ready."""
    forged = {
        "observedGeneration": 3,
        "conditions": [FORGED_READY],
        "tree": {"rootStatus": "RUNNING", "updatedAt": "not a time"},
    }
    new = _status_pass(forged, ready=False)
    ready = next(c for c in new["conditions"] if c["type"] == "Ready")
    assert (ready["status"], ready["reason"]) == ("False", "WaitingForDrivers")
    tree = next(c for c in new["conditions"] if c["type"] == "TreeHealthy")
    assert "status.tree.updatedAt: 'not a time' is not an RFC 3339 time" in tree["message"]


def test_a_long_forged_value_is_quoted_short() -> None:
    report = executor_report.read_executor_report({"tree": {"updatedAt": "x" * 100_000}})
    assert report.tree is None and len(report.ignored_tree[0]) < 120


def test_a_readable_report_is_kept_whole(spec_dict: Callable[..., dict[str, Any]]) -> None:
    tree = {
        "rootStatus": "FAILURE",
        "activePath": "Main/Nav",
        "tickCount": 12,
        "lastTransitionTime": "2026-01-01T11:00:00Z",
        "lastFailure": {"path": "Main/Nav", "message": "timeout", "time": "2026-01-01T11:00:00Z"},
        "message": "",
        "updatedAt": "2026-01-01T11:00:01Z",
    }
    plugins = {"loaded": ["slam"], "missing": [], "conflicts": [], "degraded": []}
    report = executor_report.read_executor_report({"tree": tree, "plugins": plugins})
    assert report.tree is not None and report.plugins is not None
    read = (report.tree.to_patch(), report.plugins.to_patch())
    assert (*read, report.ignored_tree, report.ignored_plugins) == (
        tree,
        plugins,
        [],
        [],
    )
