"""The executor's Kubernetes sink patches the instance's status on change, rate limited."""

from __future__ import annotations

from typing import Any

from coral.executor import kubernetes_sink as sink


class Clock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def _status(root: str, tick: int, active: str = "") -> dict[str, Any]:
    return {"event": "status", "root_status": root, "tick_count": tick, "active_path": active}


def _sink(patches: list[dict[str, Any]], clock: Clock) -> sink.KubernetesStatusSink:
    return sink.KubernetesStatusSink(
        patches.append, min_interval_s=1.0, clock=clock, wall=lambda: 0.0, background=False
    )


def test_a_status_record_becomes_the_tree_summary() -> None:
    state = sink.summarize(
        {},
        {
            "event": "status",
            "root_status": "RUNNING",
            "tick_count": 12,
            "active_path": "Main/Seq/Move",
            "last_failure": {"path": "Main/Seq/Check", "message": "no scan", "time": 0.0},
            "conditions": [{"type": "LibraryDegraded", "status": "True", "message": "slam died"}],
        },
    )
    assert state["tree"] == {
        "rootStatus": "RUNNING",
        "tickCount": 12,
        "activePath": "Main/Seq/Move",
        "lastFailure": {"path": "Main/Seq/Check", "message": "no scan", "time": "1970-01-01T00:00:00Z"},
        "message": "",
    }
    assert state["plugins"]["degraded"] == ["slam died"]


def test_waiting_and_plugin_records_fill_the_plugin_summary() -> None:
    state = sink.summarize({}, {"event": "waiting", "missing": ["EstimatePose"]})
    state = sink.summarize(
        state,
        {
            "event": "plugins",
            "loaded": [{"component": "slam", "behaviors": ["EstimatePose"]}],
            "conflicts": [],
            "refused": [],
        },
    )
    state = sink.summarize(state, {"event": "condition", "type": "PluginsReady", "status": "True"})
    assert state["plugins"] == {"missing": [], "loaded": ["slam"], "conflicts": []}
    assert state["tree"]["message"] == "Waiting for node types: EstimatePose"


def test_transitions_alone_change_nothing() -> None:
    assert sink.summarize({}, {"event": "transition", "path": "a"}) == {}


def test_it_patches_on_change_only_and_at_most_once_per_interval() -> None:
    patches: list[dict[str, Any]] = []
    clock = Clock()
    status_sink = _sink(patches, clock)
    status_sink.emit(_status("RUNNING", 1))
    assert len(patches) == 1 and patches[0]["status"]["tree"]["tickCount"] == 1
    status_sink.emit(_status("RUNNING", 2))
    assert len(patches) == 1, "a second change within the interval waits"
    clock.now += 1.5
    status_sink.emit(_status("RUNNING", 2))
    assert len(patches) == 2 and patches[1]["status"]["tree"]["tickCount"] == 2
    clock.now += 5
    status_sink.emit(_status("RUNNING", 2))
    assert len(patches) == 2, "an unchanged summary is not written again"


def test_close_flushes_the_last_pending_summary() -> None:
    patches: list[dict[str, Any]] = []
    status_sink = _sink(patches, Clock())
    status_sink.emit(_status("RUNNING", 1))
    status_sink.emit(_status("SUCCESS", 9))
    status_sink.close()
    assert patches[-1]["status"]["tree"]["rootStatus"] == "SUCCESS"


def test_a_failing_patch_never_raises_into_the_executor() -> None:
    def refuse(_: dict[str, Any]) -> None:
        raise RuntimeError("forbidden")

    status_sink = sink.KubernetesStatusSink(refuse, clock=Clock(), background=False)
    status_sink.emit(_status("RUNNING", 1))
    assert status_sink.patches == 0
