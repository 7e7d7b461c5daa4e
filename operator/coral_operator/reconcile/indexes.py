"""The in-memory indexes the reconcilers read observed state from.

kopf fills them from its watches (`handlers.indexing`) and hands them to its handlers only; the
handlers attach them here on their first event. Read from the queue's worker threads, while kopf
changes them on its event loop: a read that meets a change in flight is repeated.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterable, Mapping
from typing import Any

ALL_ROBOTS = "all"
"""The key under which `robot_nodes` holds every robot (besides `("node", NAME)` per Node)."""

# `coral_instances` holds three kinds of key, so kopf calls one handler per instance event, not
# one per view (a call costs kopf far more than building the values).


def instances_of_system(namespace: str, system: str) -> tuple[str, str, str]:
    """`coral_instances` key of a system's instances as it sees them (`ObservedInstance`)."""
    return ("system", namespace, system)


def instance_named(namespace: str, name: str) -> tuple[str, str, str]:
    """`coral_instances` key of one instance as its own reconciler reads it (`InstanceRecord`)."""
    return ("instance", namespace, name)


def instances_on_node(node_name: str) -> tuple[str, str]:
    """`coral_instances` key of the (namespace, name) of every instance on one robot's Node."""
    return ("node", node_name)


def config_maps_of_system(namespace: str, system_label: str) -> tuple[str, str]:
    """`revision_config_maps` key of the (name, owner uids) of a system's revision ConfigMaps;
    `system_label` is the value of the system's label (`planning.naming.label_value`)."""
    return (namespace, system_label)


class Indexes:
    """Named read-only views of kopf's indexes (mappings of key to a collection of values)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._indexes: dict[str, Mapping[Any, Any]] = {}

    def attach(self, **indexes: Mapping[Any, Any]) -> None:
        with self._lock:
            self._indexes.update(indexes)

    def read(self, name: str, key: Any) -> list[Any]:
        """The values under `key` of the named index; empty before it is attached."""
        return self._copy(name, lambda index: index.get(key, []))

    def count(self, name: str, key: Any) -> int:
        """How many values the named index holds under `key`, without copying them."""
        with self._lock:
            index = self._indexes.get(name)
        return len(index.get(key, ())) if index is not None else 0

    def keys(self, name: str) -> list[Any]:
        """The keys of the named index."""
        return self._copy(name, lambda index: index)

    def _copy(self, name: str, part: Callable[[Mapping[Any, Any]], Iterable[Any]]) -> list[Any]:
        with self._lock:
            index = self._indexes.get(name)
        if index is None:
            return []
        while True:
            try:
                return list(part(index))
            except RuntimeError:
                continue
