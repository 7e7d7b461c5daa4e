"""The executor's Prometheus metrics, served on `--metrics-port` (docs/metrics.md).

A status sink: it reads the records every other sink reads (transitions, status, plugins,
components) and the tick loop's tick durations, and serves them from a registry of its own. Label
values are statuses and node types (bounded by the tree), never a node's path.
"""

from __future__ import annotations

import time
from typing import Any

from coral_core.instance_status import ROOT_STATUSES
from prometheus_client import CollectorRegistry, Counter, Gauge, Histogram, start_http_server

from coral.executor import records

# The end of a mission says HALTED (stopped) or ERROR (the engine failed); the root then is idle
# or failed.
_FINISHED_AS = {"HALTED": "IDLE", "ERROR": "FAILURE"}
COMPONENT_STATES = ("alive", "degraded", "unknown")
TICK_BUCKETS_S = (0.0005, 0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0)
BEHAVIOR_BUCKETS_S = (0.001, 0.01, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0, 30.0, 60.0, 300.0)


class ExecutorMetrics:
    """A status sink keeping the executor's metrics, on `registry`."""

    def __init__(self, registry: CollectorRegistry) -> None:
        self._registry = registry
        self._server: Any = None
        self._thread: Any = None
        self.ticks = Counter("coral_executor_ticks", "Ticks of the tree.", registry=registry)
        self.tick_duration = Histogram(
            "coral_executor_tick_duration_seconds",
            "How long one tick of the tree ran.",
            buckets=TICK_BUCKETS_S,
            registry=registry,
        )
        self.tree_status = Gauge(
            "coral_executor_tree_status",
            "1 for the current status of the tree's root.",
            ["status"],
            registry=registry,
        )
        self.behavior_results = Counter(
            "coral_executor_behavior_results",
            "Nodes that finished, by node type and result (SUCCESS, FAILURE, or HALTED while running).",
            ["behavior", "result"],
            registry=registry,
        )
        self.behavior_duration = Histogram(
            "coral_executor_behavior_duration_seconds",
            "From a node's start to its result, by node type.",
            ["behavior"],
            buckets=BEHAVIOR_BUCKETS_S,
            registry=registry,
        )
        self.plugins = Gauge(
            "coral_executor_plugins",
            "Plugin libraries loaded, refused (incompatible or corrupt) and in conflict (a behavior "
            "exported twice).",
            ["state"],
            registry=registry,
        )
        self.components = Gauge(
            "coral_executor_components",
            "Components whose behaviors the tree uses, by liveness.",
            ["state"],
            registry=registry,
        )
        self._running_since: dict[str, float] = {}
        self._component_states: dict[str, str] = {}
        self._set_root("IDLE")
        for state in ("loaded", "refused", "conflict"):
            self.plugins.labels(state).set(0)
        for state in COMPONENT_STATES:
            self.components.labels(state).set(0)

    def observe_tick(self, duration_s: float) -> None:
        self.ticks.inc()
        self.tick_duration.observe(duration_s)

    def emit(self, record: records.Record) -> None:
        event = record["event"]
        if event == "transition":
            self._transition(record["path"], record["node_id"], record["previous"], record["status"])
        elif event == "status":
            self._set_root(record["root_status"])
        elif event == "finished":
            self._set_root(_FINISHED_AS.get(record["root_status"], record["root_status"]))
        elif event == "plugins":
            self.plugins.labels("loaded").set(len(record["loaded"]))
            self.plugins.labels("refused").set(len(record["refused"]))
            self.plugins.labels("conflict").set(len(record["conflicts"]))
        elif event == "component":
            self._component_states[record["component"]] = record["state"]
            for state in COMPONENT_STATES:
                self.components.labels(state).set(
                    sum(1 for known in self._component_states.values() if known == state)
                )

    def _transition(self, path: str, behavior: str, previous: str, status: str) -> None:
        now = time.monotonic()
        if status == "RUNNING":
            self._running_since[path] = now
            return
        started = self._running_since.pop(path, None)
        if status in ("SUCCESS", "FAILURE"):
            result = status
        elif previous == "RUNNING" and status == "IDLE":
            result = "HALTED"
        else:
            return
        self.behavior_results.labels(behavior, result).inc()
        # A node that answered within its first tick never ran: its duration is 0.
        self.behavior_duration.labels(behavior).observe(0.0 if started is None else now - started)

    def _set_root(self, status: str) -> None:
        if status not in ROOT_STATUSES:
            return
        for known in ROOT_STATUSES:
            self.tree_status.labels(known).set(1 if known == status else 0)

    def serve(self, address: str, port: int) -> None:
        """Serve `/metrics` on `address:port` from a thread of prometheus_client's until `close`."""
        self._server, self._thread = start_http_server(port, addr=address, registry=self._registry)

    def close(self) -> None:
        if self._server is not None:
            self._server.shutdown()
            self._server.server_close()
            self._thread.join(timeout=5)
            self._server = None
