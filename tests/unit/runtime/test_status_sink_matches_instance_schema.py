"""Contract: whatever the executor reports, its Kubernetes sink writes a status the CRD accepts.

The sink is robot-side code (`coral.executor.kubernetes_sink`); the schema is the operator's
pydantic model the CoralInstance CRD is generated from. The two packages never import each other,
so this test is what keeps them in step: a renamed status key or a new root status on either side
fails here, not on a robot whose patches the API server refuses.
"""

from __future__ import annotations

from typing import Any

from coral.executor import kubernetes_sink
from coral_core.bt.status import Status
from coral_core.instance_status import CoralInstanceStatus
from coral_core.names import GROUP, VERSION
from hypothesis import given, settings
from hypothesis import strategies as st

_TEXT = st.text(max_size=40)
_TIME = st.one_of(st.none(), st.floats(min_value=0, max_value=4e9, allow_nan=False))
_CONDITION = st.fixed_dictionaries(
    {
        "type": st.sampled_from(["PluginsReady", "LibraryDegraded"]),
        "status": st.sampled_from(["True", "False"]),
        "reason": _TEXT,
        "message": _TEXT,
        "lastTransitionTime": _TIME,
    }
)
# The records the executor emits (`coral.executor.ticking`, `running`, `plugins_phase`), with
# every root status its engine can report.
_RECORDS = st.one_of(
    st.fixed_dictionaries(
        {
            "event": st.just("status"),
            "root_status": st.sampled_from([status.name for status in Status]),
            "tick_count": st.integers(min_value=0, max_value=2**40),
            "active_path": _TEXT,
            "last_transition_time": _TIME,
            "last_failure": st.one_of(
                st.none(),
                st.fixed_dictionaries({"path": _TEXT, "message": _TEXT, "node_id": _TEXT, "time": _TIME}),
            ),
            "no_progress": st.one_of(
                st.none(),
                st.fixed_dictionaries({"path": _TEXT, "message": _TEXT, "node_id": _TEXT, "since": _TIME}),
            ),
            "conditions": st.lists(_CONDITION, max_size=2),
        }
    ),
    st.fixed_dictionaries({"event": st.just("waiting"), "missing": st.lists(_TEXT, max_size=3)}),
    st.fixed_dictionaries(
        {
            "event": st.just("plugins"),
            "loaded": st.lists(
                st.fixed_dictionaries({"component": _TEXT, "behaviors": st.lists(_TEXT, max_size=2)}),
                max_size=3,
            ),
            "refused": st.lists(st.fixed_dictionaries({"plugin": _TEXT, "reason": _TEXT}), max_size=2),
            "conflicts": st.lists(st.fixed_dictionaries({"message": _TEXT}), max_size=2),
        }
    ),
    _CONDITION.map(lambda condition: {"event": "condition", **condition}),
    st.fixed_dictionaries({"event": st.just("error"), "message": _TEXT}),
    st.fixed_dictionaries(
        {
            "event": st.just("finished"),
            "root_status": st.sampled_from(["IDLE", "ERROR", "HALTED", "SUCCESS", "FAILURE"]),
            "exit_code": st.integers(min_value=0, max_value=255),
        }
    ),
    st.fixed_dictionaries({"event": st.just("transition"), "path": _TEXT, "status": _TEXT}),
)


@settings(max_examples=300, deadline=None)
@given(st.lists(_RECORDS, min_size=1, max_size=12))
def test_every_patch_the_sink_sends_is_a_valid_instance_status(records: list[dict[str, Any]]) -> None:
    patches: list[dict[str, Any]] = []
    sink = kubernetes_sink.KubernetesStatusSink(patches.append, min_interval_s=0.0, background=False)
    for record in records:
        sink.emit(record)
    sink.close()
    for patch in patches:
        assert set(patch) == {"status"}
        # `extra="forbid"` on the models: a key the schema does not know fails here.
        CoralInstanceStatus.model_validate(patch["status"])


def test_the_sink_writes_only_the_status_fields_the_executor_owns() -> None:
    patches: list[dict[str, Any]] = []
    sink = kubernetes_sink.KubernetesStatusSink(patches.append, min_interval_s=0.0, background=False)
    sink.emit({"event": "status", "root_status": "RUNNING", "tick_count": 3, "active_path": "Main/Move"})
    sink.emit({"event": "waiting", "missing": ["Dock"]})
    sink.close()
    written = {key for patch in patches for key in patch["status"]}
    assert written == {"tree", "plugins"}
    executor_fields = {
        field.alias or name
        for name, field in CoralInstanceStatus.model_fields.items()
        if name in ("tree", "plugins")
    }
    assert written == executor_fields


def test_the_sink_patches_the_resource_the_crd_serves() -> None:
    calls: list[tuple[Any, ...]] = []

    class RecordingApi:
        """Stands in for the client: this checks the address the sink writes to, not the API."""

        def patch_namespaced_custom_object_status(self, *args: Any, **kwargs: Any) -> None:
            calls.append(args)

    patcher = kubernetes_sink.build_patcher(None, "fleet", "patrol-r1", api=RecordingApi())
    patcher({"status": {"tree": {"rootStatus": "RUNNING"}}})
    assert calls == [
        (
            GROUP,
            VERSION,
            "fleet",
            "coralinstances",
            "patrol-r1",
            {"status": {"tree": {"rootStatus": "RUNNING"}}},
        )
    ]
