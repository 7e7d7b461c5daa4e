"""Test doubles of the tick loop's tests: a record collector and behaviors that fail at once."""

from __future__ import annotations

import time
from types import SimpleNamespace
from typing import Any

from coral.executor import plugins_phase, sinks
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
    executor's context notes them; `options` go to TickLoop."""
    registry = NodeRegistry.with_builtins()
    for name, behavior in behaviors.items():
        registry.register(name, behavior)
    failures: dict[str, str] = {}
    context = SimpleNamespace(
        health=HealthMonitor(time.monotonic),
        failures=failures,
        failure_message=lambda path: failures.pop(path, ""),
    )
    tree = build_tree(load_tree_text(xml), registry, context=context)
    state = plugins_phase.PluginState(used=set(), builtin_ids=set())
    return TickLoop(tree, context, sinks.SinkFanout([collect]), state, **options)
