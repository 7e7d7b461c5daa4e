"""The fleet's state as metrics, computed when Prometheus scrapes: robots by state, instances by
condition and tree state per system, rollout progress per system, and the work queue's depth and
longest wait. One scrape reads the indexes once (a thousand robots: a few milliseconds); the
number of series grows with systems, never with robots."""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Iterator, Sequence
from typing import Any, Protocol

from prometheus_client.core import GaugeMetricFamily
from prometheus_client.registry import Collector

from coral_operator.api import keys
from coral_operator.planning.observed import ObservedInstance, RobotNode, SystemRecord
from coral_operator.reconcile.indexes import ALL_ROBOTS, Indexes, instances_of_system

ROBOT_STATES = ("ready", "not_ready", "unreachable")
TREE_STATES = ("NONE", "IDLE", "RUNNING", "SUCCESS", "FAILURE", "SKIPPED")
"""`NONE`: the executor has reported no tree yet."""
CONDITIONS = ("Ready", "Stalled", "RobotReachable")
ROLLOUT_COUNTS = ("total", "updated", "healthy", "unavailable", "locked", "offline", "failed")


class Queue(Protocol):
    def __len__(self) -> int: ...

    def longest_wait_s(self) -> float: ...


def robot_state(robot: RobotNode) -> str:
    if not robot.reachable:
        return "unreachable"
    return "ready" if robot.ready else "not_ready"


def robot_families(robots: Iterable[RobotNode]) -> list[GaugeMetricFamily]:
    counts = Counter(robot_state(robot) for robot in robots)
    family = GaugeMetricFamily(
        "coral_robots",
        "Robot Nodes (labelled coral.dev/robot) by state: ready, not_ready (the kubelet reports "
        "NotReady) or unreachable (no heartbeat; the Node is tainted unreachable).",
        labels=["state"],
    )
    for state in ROBOT_STATES:
        family.add_metric([state], counts[state])
    return [family]


def _condition_status(instance: ObservedInstance, condition: str) -> str:
    if condition == "Ready":
        return "True" if instance.ready else "False"
    if condition == "Stalled":
        return "True" if instance.stalled else "False"
    return {True: "True", False: "False"}.get(instance.reachable, "Unknown")  # type: ignore[arg-type]


def instance_families(
    systems: Iterable[tuple[tuple[str, str], Sequence[ObservedInstance]]],
) -> list[GaugeMetricFamily]:
    """Per system: instances by condition and status, and by the state of their tree's root."""
    conditions = GaugeMetricFamily(
        "coral_instances",
        "CoralInstances (one per robot of a system) by condition (Ready, Stalled, RobotReachable) "
        "and its status.",
        labels=["namespace", "system", "condition", "status"],
    )
    trees = GaugeMetricFamily(
        "coral_instance_trees",
        "CoralInstances by the status of their tree's root as the executor reports it (NONE: no report yet).",
        labels=["namespace", "system", "state"],
    )
    for (namespace, system), instances in systems:
        for condition in CONDITIONS:
            counts = Counter(_condition_status(instance, condition) for instance in instances)
            for status in ("True", "False", "Unknown"):
                if status == "Unknown" and condition != "RobotReachable":
                    continue
                conditions.add_metric([namespace, system, condition, status], counts[status])
        states = Counter(instance.root_status or "NONE" for instance in instances)
        for state in TREE_STATES:
            trees.add_metric([namespace, system, state], states[state])
    return [conditions, trees]


def rollout_families(systems: Iterable[SystemRecord]) -> list[GaugeMetricFamily]:
    """Per system: the rollout's robot counts and whether it is complete or paused."""
    robots = GaugeMetricFamily(
        "coral_rollout_robots",
        "Robots of a system's rollout by count (total, updated to the target revision, healthy, "
        "unavailable, locked by a running tree, offline, failed the health gate).",
        labels=["namespace", "system", "count"],
    )
    complete = GaugeMetricFamily(
        "coral_rollout_complete",
        "1 when every robot taking part runs the system's target revision.",
        labels=["namespace", "system"],
    )
    paused = GaugeMetricFamily(
        "coral_rollout_paused",
        "1 when the rollout moves no robot (spec.rollout.paused, or a failure with onFailure: Pause).",
        labels=["namespace", "system"],
    )
    for record in systems:
        rollout = _mapping(record.status.get(keys.SYSTEM_STATUS.rollout))
        counts = _mapping(rollout.get(keys.ROLLOUT.counts))
        for count in ROLLOUT_COUNTS:
            value = counts.get(getattr(keys.ROLLOUT_COUNTS, count))
            robots.add_metric([record.namespace, record.name, count], value if isinstance(value, int) else 0)
        complete.add_metric([record.namespace, record.name], bool(rollout.get(keys.ROLLOUT.complete)))
        paused.add_metric([record.namespace, record.name], bool(rollout.get(keys.ROLLOUT.paused)))
    return [robots, complete, paused]


def queue_families(depth: int, longest_wait_s: float) -> list[GaugeMetricFamily]:
    return [
        GaugeMetricFamily(
            "coral_operator_workqueue_depth",
            "Keys waiting for a reconcile pass or in one.",
            value=depth,
        ),
        GaugeMetricFamily(
            "coral_operator_workqueue_longest_wait_seconds",
            "How long the key that is most overdue has waited for a worker (0 when none is due).",
            value=longest_wait_s,
        ),
    ]


class FleetCollector(Collector):
    """Reads the controller's indexes and queue at each scrape."""

    def __init__(self, indexes: Indexes, queue: Queue) -> None:
        self._indexes = indexes
        self._queue = queue

    def collect(self) -> Iterator[GaugeMetricFamily]:
        yield from robot_families(self._indexes.read("robot_nodes", ALL_ROBOTS))
        per_system = [
            ((key[1], key[2]), self._indexes.read("coral_instances", key))
            for key in self._indexes.keys("coral_instances")
            if len(key) == 3 and key == instances_of_system(key[1], key[2])
        ]
        # A system whose instances are all gone still has its series (at zero), so an alert
        # comparing counts does not see it vanish.
        known = {system for system, _ in per_system}
        records = [
            record
            for key in self._indexes.keys("coral_systems")
            for record in self._indexes.read("coral_systems", key)
        ]
        per_system += [((r.namespace, r.name), []) for r in records if (r.namespace, r.name) not in known]
        yield from instance_families(sorted(per_system, key=lambda item: item[0]))
        yield from rollout_families(records)
        yield from queue_families(len(self._queue), self._queue.longest_wait_s())


def _mapping(value: Any) -> dict[str, Any]:
    return value if isinstance(value, dict) else {}
