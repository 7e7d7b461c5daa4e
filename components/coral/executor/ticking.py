"""The tick loop: ticks on wake-ups, and at the configured rate only while the tree needs polling.

BT.CPP's model (`emitWakeUpSignal`): a behavior whose RUNNING state changes on an event (a service
response, a message, a timer) wakes the tree when it happens. While every RUNNING node keeps that
contract (`Tree.needs_polling()` is False) the loop sleeps until a wake-up, a behavior's booked
deadline (`ExecutorContext.wakeups`), the moment a component would turn silent, or the status
heartbeat, whichever comes first; otherwise it ticks at the configured rate as well.

The configured rate is also the most the loop ticks, wake-ups included: a tick starts no sooner
than one period after the one before. A wake-up that comes later than that ticks at once; an
earlier one waits for the period to end. Without the bound, a behavior that fails at once inside
a retry wakes the tree again from its own tick, and a robot whose skillset lost its state spun at
400 ticks a second with its rate set to 20 (issue 50).

Used by `coral.executor.running` once the tree is built. Status records go to the sinks:
every node transition, `component` records when a loaded component's liveness changes
(`unknown`, `alive`, `degraded`), a `status` record when the root status or active node changes (at most
5 per second, plus one per second as a heartbeat), and `condition` records for `LibraryDegraded`.
A `status` record's `no_progress` names the node that keeps failing the same way
(`coral.executor.progress`), or is null.

While its `HaltSignal` holds a request, the loop halts the tree (`coral.executor.halting`), reports
a `halted` record and ticks no more; when the request is lifted it reports `resumed` and ticks the
tree again from its start.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any

from coral_core.limits import DEFAULT_NO_PROGRESS_S

from coral.executor import plugins_phase, records, sinks
from coral.executor.halting import HaltOutcome, HaltSignal, ParkBuilder, halt_tree
from coral.executor.progress import ProgressWatch

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
        no_progress_s: float = DEFAULT_NO_PROGRESS_S,
        halts: HaltSignal | None = None,
        build_park: ParkBuilder | None = None,
        on_tick: Callable[[float], None] | None = None,
    ) -> None:
        """`on_tick(duration_s)` is told of every tick as it ends (the executor's metrics)."""
        self.tree = tree
        self._on_tick = on_tick
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
        self.progress = ProgressWatch(no_progress_s)
        self.halts = halts
        self.build_park = build_park
        self.halted: HaltOutcome | None = None
        """Set while the tree is halted on request."""
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
        if status == "SUCCESS":
            self.progress.succeeded(transition.path)
        if status != "FAILURE":
            return
        message = self.context.failure_message(transition.path)
        self.progress.failed(
            transition.path, transition.node_id, message, time.monotonic(), self.last_transition_time
        )
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
            "root_status": records.status_name(root),
            "tick_count": self.tree.tick_count,
            "active_path": records.active_path(snapshot.nodes),
            "last_transition_time": self.last_transition_time,
            "last_failure": self.last_failure,
            "no_progress": self.progress.stuck(time.monotonic()),
            "conditions": conditions,
        }

    def _report(self, root: Any, force: bool = False) -> None:
        now = time.monotonic()
        last = self._last_status
        root_changed = last is None or last["root_status"] != records.status_name(root)
        if not (force or root_changed or now - self._last_status_at >= STATUS_MIN_INTERVAL_S):
            return  # nothing could be due: skip building the record (a snapshot of every node)
        record = self.status_record(root)
        comparable = {k: v for k, v in record.items() if k not in ("tick_count", "last_transition_time")}
        previous = None
        if self._last_status is not None:
            previous = {
                k: v for k, v in self._last_status.items() if k not in ("tick_count", "last_transition_time")
            }
        due = (comparable != previous and now - self._last_status_at >= STATUS_MIN_INTERVAL_S) or (
            now - self._last_status_at >= STATUS_HEARTBEAT_S
        )
        if force or root_changed or due:
            self._emit("status", **record)
            self._last_status = record
            self._last_status_at = now

    def run(self, stop: threading.Event, stop_code: Callable[[], int]) -> int:
        from coral_core import bt

        root: Any = bt.Status.IDLE
        try:
            while not stop.is_set():
                if self._follow_halt(stop):
                    root = bt.Status.IDLE
                    # The halt signal wakes the tree when it changes; the heartbeat is a backstop.
                    self.tree.wait_for_wake_up(STATUS_HEARTBEAT_S)
                    continue
                started = time.monotonic()
                root = self.tree.tick_exactly_once()
                if self._on_tick is not None:
                    self._on_tick(time.monotonic() - started)
                self.fanout.end_tick()
                self._check_degraded()
                if root in (bt.Status.SUCCESS, bt.Status.FAILURE):
                    break
                self._report(root)
                self.tree.wait_for_wake_up(self._sleep_s(started))
                # Never sooner than a period after this tick began, however early the wake-up.
                stop.wait(max(0.0, started + self.period_s - time.monotonic()))
        except bt.BTRuntimeError as err:
            self._emit("error", message=str(err))
            self._halt()
            self._report(bt.Status.FAILURE, force=True)
            self._emit("finished", root_status="ERROR", exit_code=3, tick_count=self.tree.tick_count)
            return 3
        if stop.is_set() and root not in (bt.Status.SUCCESS, bt.Status.FAILURE):
            self._halt()
            code = stop_code()
            self._report(bt.Status.IDLE, force=True)
            self._emit("finished", root_status="HALTED", exit_code=code, tick_count=self.tree.tick_count)
            return code
        self._report(root, force=True)
        code = 0 if root == bt.Status.SUCCESS else 1
        self._emit(
            "finished", root_status=records.status_name(root), exit_code=code, tick_count=self.tree.tick_count
        )
        return code

    def _follow_halt(self, stop: threading.Event) -> bool:
        """Halts or resumes as the halt signal asks; True while the tree stays halted.

        A halt reports an IDLE status and then `halted` once done; a resume reports `resumed`, and
        the next tick starts the tree from its beginning, as the halt reset every node.
        """
        from coral_core import bt

        request = self.halts.current() if self.halts is not None else None
        if request is None:
            if self.halted is not None:
                self.halted = None
                self._emit("resumed")
            return False
        if self.halted is None:
            self.halted = halt_tree(self.tree, request, self.build_park, period_s=self.period_s, stop=stop)
            if self.halted.error:
                self._emit("error", message=f"halt (park tree {request.park_tree}): {self.halted.error}")
            # The IDLE status first, so the acknowledgement (written at once) carries it along.
            self._report(bt.Status.IDLE, force=True)
            self._emit("halted", **self.halted.record_fields())
        return True

    def _sleep_s(self, tick_started: float) -> float:
        """How long to wait for a wake-up before ticking anyway."""
        now = time.monotonic()
        if self.tree.needs_polling():
            return max(0.0, tick_started + self.period_s - now)
        until = now + STATUS_HEARTBEAT_S
        wakeups = getattr(self.context, "wakeups", None)
        booked = wakeups.next_due(now) if wakeups is not None else None
        silent = self.context.health.next_failure_at(self.plugins.components_in_use())
        for when in (booked, silent):
            if when is not None:
                until = min(until, when)
        return max(0.0, until - now)

    def _halt(self) -> None:
        try:
            self.tree.halt()
        except Exception as err:  # noqa: BLE001 - report, then keep shutting down
            self._emit("error", message=f"halting the tree failed: {err}")
