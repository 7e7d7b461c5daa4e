"""The tick loop: ticks at the configured rate and at once on wake-ups, reports status, halts cleanly.

Used by `coral.executor.running` once the tree is built. Status records go to the sinks:
every node transition, `component` records when a loaded component's liveness changes
(`unknown`, `alive`, `degraded`), a `status` record when the root status or active node changes (at most
5 per second, plus one per second as a heartbeat), and `condition` records for `LibraryDegraded`.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any

from coral.executor import plugins_phase, records, sinks

STATUS_MIN_INTERVAL_S = 0.2
STATUS_HEARTBEAT_S = 1.0


class TickLoop:
    def __init__(
        self,
        tree: Any,
        context: Any,
        fanout: sinks.SinkFanout,
        plugins: plugins_phase.PluginState,
        *,
        rate_hz: float,
    ) -> None:
        self.tree = tree
        self.context = context
        self.fanout = fanout
        self.plugins = plugins
        self.period_s = 1.0 / rate_hz if rate_hz > 0 else 0.1
        self.last_failure: dict[str, Any] | None = None
        self._failure_tick = -1
        self.last_transition_time = 0.0
        self._degraded: records.Condition | None = None
        self._component_states: dict[str, str] = {}
        self._last_status: dict[str, Any] | None = None
        self._last_status_at = 0.0
        tree.add_transition_listener(self._on_transition)

    def _emit(self, event: str, **fields: Any) -> None:
        self.fanout.emit({"ts": time.time(), "event": event, **fields})

    def _on_transition(self, transition: Any) -> None:
        previous = records.status_name(transition.previous)
        status = records.status_name(transition.status)
        self.last_transition_time = time.time()
        self._emit(
            "transition",
            path=transition.path,
            node_id=transition.node_id,
            previous=previous,
            status=status,
            tick=self.tree.tick_count,
        )
        if status != "FAILURE":
            return
        message = self.context.failure_message(transition.path)
        # Transitions propagate leaf-first, so the first FAILURE of a tick is where it started;
        # but a condition that said no before a Fallback went on to its next child explains
        # nothing, so a later failure of the same tick that says why it failed (a behavior whose
        # skillset is gone) takes its place.
        first = self._failure_tick != self.tree.tick_count
        if first or (message and not (self.last_failure or {}).get("message")):
            self._failure_tick = self.tree.tick_count
            self.last_failure = {
                "path": transition.path,
                "node_id": transition.node_id,
                "message": message,
                "time": self.last_transition_time,
            }

    def _check_degraded(self) -> None:
        health = self.context.health
        for component in sorted(self.plugins.components_in_use()):
            state = health.state(component)
            if self._component_states.get(component) != state:
                self._component_states[component] = state
                self._emit(
                    "component", component=component, state=state, reason=health.failure(component) or ""
                )
        degraded = health.degraded(self.plugins.components_in_use())
        condition = records.library_degraded_condition(self._degraded, degraded, time.time())
        changed = self._degraded is None or (condition.status, condition.message) != (
            self._degraded.status,
            self._degraded.message,
        )
        if changed and (self._degraded is not None or condition.status == "True"):
            self._emit("condition", **condition.as_dict())
        self._degraded = condition

    def wait_for_components(self, timeout_s: float, stop: threading.Event) -> None:
        """Before the first tick, waits (bounded) until every component in use was heard alive.

        A heartbeat heard means DDS discovery between the two processes is done, so the first
        service call does not spend its timeout waiting for the service to be discovered.
        """
        deadline = time.monotonic() + timeout_s
        while not stop.is_set():
            self._check_degraded()
            states = [self._component_states.get(c) for c in self.plugins.components_in_use()]
            # A component already degraded will not come back by waiting: its calls fail fast.
            if all(state in ("alive", "degraded") for state in states) or time.monotonic() >= deadline:
                return
            self.tree.wait_for_wake_up(0.05)

    def status_record(self, root: Any) -> dict[str, Any]:
        snapshot = self.tree.snapshot()
        conditions = [c.as_dict() for c in (self.plugins.plugins_ready, self._degraded) if c is not None]
        return {
            "root": records.status_name(root),
            "tick_count": self.tree.tick_count,
            "active_path": records.active_path(snapshot.nodes),
            "last_transition_time": self.last_transition_time,
            "last_failure": self.last_failure,
            "conditions": conditions,
        }

    def _report(self, root: Any, force: bool = False) -> None:
        record = self.status_record(root)
        now = time.monotonic()
        comparable = {k: v for k, v in record.items() if k not in ("tick_count", "last_transition_time")}
        previous = None
        if self._last_status is not None:
            previous = {
                k: v for k, v in self._last_status.items() if k not in ("tick_count", "last_transition_time")
            }
        root_changed = self._last_status is None or self._last_status["root"] != record["root"]
        due = (comparable != previous and now - self._last_status_at >= STATUS_MIN_INTERVAL_S) or (
            now - self._last_status_at >= STATUS_HEARTBEAT_S
        )
        if force or root_changed or due:
            self._emit("status", **record)
            self._last_status = record
            self._last_status_at = now

    def run(self, stop: threading.Event, stop_code: Callable[[], int]) -> int:
        from coral import bt

        root: Any = bt.Status.IDLE
        try:
            while not stop.is_set():
                started = time.monotonic()
                root = self.tree.tick_exactly_once()
                self._check_degraded()
                if root in (bt.Status.SUCCESS, bt.Status.FAILURE):
                    break
                self._report(root)
                # The period bounds the gap between ticks; a wake-up ticks at once and restarts it.
                self.tree.wait_for_wake_up(max(0.0, started + self.period_s - time.monotonic()))
        except bt.BTRuntimeError as err:
            self._emit("error", message=str(err))
            self._halt()
            self._report(bt.Status.FAILURE, force=True)
            self._emit("finished", root="ERROR", exit_code=3, tick_count=self.tree.tick_count)
            return 3
        if stop.is_set() and root not in (bt.Status.SUCCESS, bt.Status.FAILURE):
            self._halt()
            code = stop_code()
            self._report(bt.Status.IDLE, force=True)
            self._emit("finished", root="HALTED", exit_code=code, tick_count=self.tree.tick_count)
            return code
        self._report(root, force=True)
        code = 0 if root == bt.Status.SUCCESS else 1
        self._emit(
            "finished", root=records.status_name(root), exit_code=code, tick_count=self.tree.tick_count
        )
        return code

    def _halt(self) -> None:
        try:
            self.tree.halt()
        except Exception as err:  # noqa: BLE001 - report, then keep shutting down
            self._emit("error", message=f"halting the tree failed: {err}")
