"""What a reconciler of either kind is given: the memory, the indexes, the writer, where Events
go, how to ask for another pass, and the clock. `reconcile.instances` and `reconcile.systems` add
what only their kind needs."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from datetime import UTC, datetime

from coral_operator.kube.writer import Writer
from coral_operator.reconcile import events
from coral_operator.reconcile.indexes import Indexes
from coral_operator.reconcile.memory import Memory

Key = tuple[str, str]
"""(namespace, name) of the object a pass is for."""


def _utc_now() -> datetime:
    return datetime.now(UTC)


@dataclass(kw_only=True, eq=False)
class Reconciler:
    """The base of both kinds' reconcilers (see the module docstring)."""

    memory: Memory
    indexes: Indexes
    writer: Writer
    post: events.Poster
    requeue: Callable[[Key, float], None]
    """Pass this key again after so many seconds, even if nothing changes."""
    clock: Callable[[], datetime] = _utc_now
