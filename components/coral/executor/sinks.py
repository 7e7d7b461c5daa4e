"""Where executor status records go: the terminal, a JSON-lines file, a ROS topic, or a plugged-in sink.

A sink is any object with `emit(record)` and `close()`, and optionally `end_tick()`, which the
tick loop calls once after each tick (a sink may hold a tick's transitions until then). The executor
(`coral.executor.running`) builds the ones its options ask for; `--sink MODULE:FACTORY` adds
others (the operator's Kubernetes sink), where `FACTORY(options: dict) -> sink`. A failing sink
is reported once and then skipped, so a full disk never stops a robot's mission.
"""

from __future__ import annotations

import importlib
import json
import sys
import threading
from pathlib import Path
from typing import Any, Protocol, TextIO

from coral.executor import records


class StatusSink(Protocol):
    def emit(self, record: records.Record) -> None: ...

    def close(self) -> None: ...


class TerminalSink:
    """Human-readable lines on a stream; transitions only when `verbose`."""

    def __init__(self, stream: TextIO | None = None, *, verbose: bool = False) -> None:
        self.stream = stream or sys.stderr
        self.verbose = verbose

    def emit(self, record: records.Record) -> None:
        event = record["event"]
        if event == "transition":
            if self.verbose:
                self._line(f"{record['path']}: {record['previous']} -> {record['status']}")
            return
        if event == "status":
            failure = record.get("last_failure") or {}
            tail = (
                f" last failure at {failure['path']}: {failure['message']}" if failure.get("message") else ""
            )
            self._line(
                f"tree {record['root_status']} tick {record['tick_count']} "
                f"active {record['active_path'] or '-'}{tail}"
            )
        elif event == "waiting":
            self._line("Waiting for node types: " + ", ".join(record["missing"]))
        elif event == "plugins":
            for refusal in record["refused"]:
                self._line(f"Plugin {refusal['plugin']} refused: {refusal['reason']}")
            for conflict in record["conflicts"]:
                self._line(f"Conflict: {conflict['message']}")
            for loaded in record["loaded"]:
                self._line(f"Plugin {loaded['component']} loaded: {', '.join(loaded['behaviors']) or '-'}")
        elif event == "component":
            reason = f" ({record['reason']})" if record.get("reason") else ""
            self._line(f"Component {record['component']} {record['state']}{reason}")
        elif event == "condition":
            self._line(
                f"Condition {record['type']}={record['status']} ({record['reason']}): {record['message']}"
            )
        elif event == "groot2":
            details = {k: v for k, v in record.items() if k not in ("ts", "event")}
            self._line(f"Groot2 publisher: {json.dumps(details, sort_keys=True)}")
        elif event in ("started", "finished", "error", "halted", "resumed"):
            details = {k: v for k, v in record.items() if k not in ("ts", "event")}
            self._line(f"Executor {event}: {json.dumps(details, sort_keys=True)}")

    def _line(self, text: str) -> None:
        self.stream.write(text + "\n")
        self.stream.flush()

    def close(self) -> None:
        self.stream.flush()


class JsonLinesSink:
    """One JSON object per line, for readers (tests, the local runtime) that tail it.

    Transitions are flushed once per tick (`end_tick`), every other record at once: a tick makes
    several transitions, and a write to the file per transition was a large part of the tick's cost.
    """

    def __init__(self, path: Path) -> None:
        path.parent.mkdir(parents=True, exist_ok=True)
        self._file = path.open("a", encoding="utf-8")
        self._lock = threading.Lock()

    def emit(self, record: records.Record) -> None:
        line = json.dumps(record, sort_keys=True, default=str)
        with self._lock:
            self._file.write(line + "\n")
            if record.get("event") != "transition":
                self._file.flush()

    def end_tick(self) -> None:
        with self._lock:
            if not self._file.closed:
                self._file.flush()

    def close(self) -> None:
        with self._lock:
            self._file.close()


class RosTopicSink:
    """Publishes status, condition and finish records (not transitions) as JSON `std_msgs/String`."""

    EVENTS = {"status", "condition", "component", "finished", "waiting", "plugins", "halted", "resumed"}

    def __init__(self, node: Any, topic: str) -> None:
        from rclpy.qos import DurabilityPolicy, QoSProfile
        from std_msgs.msg import String

        self._string = String
        # Transient-local keeps the latest records for tools that attach later.
        qos = QoSProfile(depth=10, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self._publisher = node.create_publisher(String, topic, qos)

    def emit(self, record: records.Record) -> None:
        if record["event"] in self.EVENTS:
            self._publisher.publish(self._string(data=json.dumps(record, sort_keys=True, default=str)))

    def close(self) -> None:
        """Waits (at most 1 s) until subscribers have the last records: the process exits next."""
        from rclpy.duration import Duration

        self._publisher.wait_for_all_acked(Duration(seconds=1))


def load_sink(target: str, options: dict[str, Any]) -> StatusSink:
    """`package.module:factory` -> `factory(options)`; raises ValueError naming the target."""
    module_name, _, attribute = target.partition(":")
    if not module_name or not attribute:
        raise ValueError(f"sink {target!r} must be written MODULE:FACTORY")
    try:
        factory = getattr(importlib.import_module(module_name), attribute)
    except (ImportError, AttributeError) as err:
        raise ValueError(f"sink {target!r} cannot be loaded: {err}") from err
    sink: StatusSink = factory(options)
    return sink


class SinkFanout:
    """Sends each record to every sink; a sink that raises is reported once and dropped."""

    def __init__(self, sinks: list[StatusSink]) -> None:
        self._sinks = list(sinks)
        self._lock = threading.Lock()

    def add(self, sink: StatusSink) -> None:
        with self._lock:
            self._sinks.append(sink)

    def remove(self, sink: StatusSink) -> None:
        with self._lock:
            if sink in self._sinks:
                self._sinks.remove(sink)

    def emit(self, record: records.Record) -> None:
        with self._lock:
            sinks = list(self._sinks)
        for sink in sinks:
            try:
                sink.emit(record)
            except Exception as err:  # noqa: BLE001 - one broken sink must not stop the tree
                print(f"Status sink {type(sink).__name__} failed and was dropped: {err}", file=sys.stderr)
                with self._lock:
                    if sink in self._sinks:
                        self._sinks.remove(sink)

    def end_tick(self) -> None:
        """Ends a tick: sinks that hold records until then write them out."""
        with self._lock:
            sinks = [sink for sink in self._sinks if hasattr(sink, "end_tick")]
        for sink in sinks:
            try:
                sink.end_tick()
            except Exception as err:  # noqa: BLE001 - same rule as emit
                print(f"Status sink {type(sink).__name__} failed and was dropped: {err}", file=sys.stderr)
                with self._lock:
                    if sink in self._sinks:
                        self._sinks.remove(sink)

    def close(self) -> None:
        for sink in self._sinks:
            try:
                sink.close()
            except Exception:  # noqa: BLE001
                pass
