"""Test doubles of the tick loop's tests: a record collector and behaviors that fail at once."""

from __future__ import annotations

import threading
import time
from types import SimpleNamespace
from typing import Any

from coral.executor import plugins_phase, sinks
from coral.executor.halting import park_builder
from coral.executor.health import HealthMonitor
from coral.executor.ticking import TickLoop
from coral_core.bt import NodeRegistry, Status, build_tree, load_tree_text
from coral_core.bt.leaves import StatefulAction


class Collect:
    """A status sink that keeps every record."""

    def __init__(self) -> None:
        self.records: list[dict[str, Any]] = []

    def emit(self, record: dict[str, Any]) -> None:
        self.records.append(record)

    def close(self) -> None:
        pass


class FailsAtOnce(StatefulAction):
    """Fails on every run and says why, as a behavior whose skillset forgot its state does; it
    keeps BT.CPP's wake-up contract, so only its retries wake the tree."""

    SIGNALS_WAKE_UP = True
    MESSAGE = "localization is disabled"

    def on_start(self) -> Status:
        self.context.failures[self.path] = self.MESSAGE
        return Status.FAILURE

    def on_running(self) -> Status:
        return Status.FAILURE


class Refused(FailsAtOnce):
    """Fails at once and says why, as a behavior whose skillset is gone does."""

    MESSAGE = "skillset slam is unavailable: it restarted"


def build_loop(xml: str, collect: Collect, behaviors: dict[str, type], **options: Any) -> TickLoop:
    """A tick loop over the tree `xml` with the builtins and `behaviors`, its failures noted as the
    executor's context notes them, park trees built from the same document; `options` go to TickLoop."""
    registry = NodeRegistry.with_builtins()
    for name, behavior in behaviors.items():
        registry.register(name, behavior)
    failures: dict[str, str] = {}
    context = SimpleNamespace(
        health=HealthMonitor(time.monotonic),
        failures=failures,
        failure_message=lambda path: failures.pop(path, ""),
    )
    document = load_tree_text(xml)
    tree = build_tree(document, registry, context=context)
    state = plugins_phase.PluginState(used=set(), builtin_ids=set())
    options.setdefault("build_park", park_builder(document, registry, context))
    return TickLoop(tree, context, sinks.SinkFanout([collect]), state, **options)


def start(loop: TickLoop, stop: threading.Event) -> threading.Event:
    """Runs `loop` on a thread until `stop` (a SIGTERM gives 143); the event is set once it returned."""
    finished = threading.Event()

    def run() -> None:
        loop.run(stop, lambda: 143)
        finished.set()

    threading.Thread(target=run, daemon=True).start()
    return finished
