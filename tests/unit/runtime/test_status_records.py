"""Executor status records: condition transitions, JSON-lines output, sink isolation."""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace

import pytest
from coral.executor import records, sinks


def test_a_condition_keeps_its_transition_time_until_its_status_flips() -> None:
    first = records.library_degraded_condition(None, {}, now=1.0)
    same = records.library_degraded_condition(first, {}, now=2.0)
    flipped = records.library_degraded_condition(same, {"examples": "no heartbeat for 2.0 s"}, now=3.0)
    assert (first.status, same.last_transition_time) == ("False", 1.0)
    assert (flipped.status, flipped.last_transition_time, flipped.reason) == (
        "True",
        3.0,
        "ComponentUnavailable",
    )
    assert "examples (no heartbeat for 2.0 s)" in flipped.message


def test_plugins_ready_names_the_missing_node_types() -> None:
    condition = records.plugins_ready_condition(None, ["Count", "Greet"], now=1.0)
    assert condition.status == "False"
    assert condition.message.endswith("Count, Greet")


def test_the_active_path_is_the_deepest_running_node() -> None:
    nodes = [
        SimpleNamespace(path="Sequence::1", status="RUNNING"),
        SimpleNamespace(path="Greet::2", status="SUCCESS"),
        SimpleNamespace(path="Fallback::3", status="RUNNING"),
        SimpleNamespace(path="Count::4", status="RUNNING"),
    ]
    assert records.active_path(nodes) == "Count::4"
    assert records.active_path([]) == ""


def test_json_lines_sink_writes_one_parsable_record_per_line(tmp_path: Path) -> None:
    path = tmp_path / "deep" / "status.jsonl"
    sink = sinks.JsonLinesSink(path)
    sink.emit({"ts": 1.0, "event": "status", "root_status": "RUNNING"})
    sink.emit({"ts": 2.0, "event": "finished", "root_status": "SUCCESS", "exit_code": 0})
    sink.close()
    lines = [json.loads(line) for line in path.read_text().splitlines()]
    assert [line["event"] for line in lines] == ["status", "finished"]


class BrokenSink:
    def emit(self, record: records.Record) -> None:
        raise OSError("disk full")

    def close(self) -> None:
        pass


def test_a_failing_sink_is_dropped_and_the_others_keep_receiving(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    good = sinks.JsonLinesSink(tmp_path / "s.jsonl")
    fanout = sinks.SinkFanout([BrokenSink(), good])
    fanout.emit({"ts": 1.0, "event": "status", "root_status": "RUNNING"})
    fanout.emit({"ts": 2.0, "event": "status", "root_status": "RUNNING"})
    fanout.close()
    assert len((tmp_path / "s.jsonl").read_text().splitlines()) == 2
    assert capsys.readouterr().err.count("BrokenSink failed and was dropped: disk full") == 1


def test_a_plugged_in_sink_must_be_module_and_factory() -> None:
    with pytest.raises(ValueError, match="MODULE:FACTORY"):
        sinks.load_sink("nocolon", {})
    with pytest.raises(ValueError, match="cannot be loaded"):
        sinks.load_sink("coral.executor.sinks:NoSuchFactory", {})


def test_json_lines_sink_writes_a_ticks_transitions_at_its_end_and_other_records_at_once(
    tmp_path: Path,
) -> None:
    path = tmp_path / "status.jsonl"
    sink = sinks.JsonLinesSink(path)
    fanout = sinks.SinkFanout([sink])
    fanout.emit({"ts": 1.0, "event": "transition", "path": "Work::1", "status": "RUNNING"})
    assert path.read_text() == ""  # held until the tick ends
    fanout.end_tick()
    assert [json.loads(line)["event"] for line in path.read_text().splitlines()] == ["transition"]
    fanout.emit({"ts": 2.0, "event": "status", "root_status": "RUNNING"})
    assert [json.loads(line)["event"] for line in path.read_text().splitlines()] == ["transition", "status"]
    fanout.close()
