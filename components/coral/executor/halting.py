"""Halting a tree on request and resuming it: the executor's side of `spec.halt`.

`HaltSignal` holds the latest request (None: run), set by whoever follows it (the CoralInstance's
watch, `coral.executor.halt_watch`, in a cluster) and read by the tick loop before every tick.
`halt_tree` does what a halt asks: it halts the mission's tree as BT.CPP's `haltTree()` does (every
running node halted, every status reset, so the next tick starts the tree from its beginning),
then ticks the park tree, if one is named, until it ends or its time is up, and halts that too.

The mission is halted before the park tree starts, so the two never command the robot at once.
A halt is an operational stop: it stops the tree ticking, not the robot's drivers or skillsets.
"""

from __future__ import annotations

import dataclasses
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from coral_core.halt import HaltRequest
from coral_core.instance_status import ParkStatus

ParkBuilder = Callable[[str], Any]
"""Builds the tree of the given `<BehaviorTree>` ID of the mission's document; raises
`coral_core.bt.BTError` when it cannot."""


class HaltSignal:
    """The latest halt request, shared between the thread that follows it and the tick loop."""

    def __init__(self, wake: Callable[[], None] = lambda: None) -> None:
        self._wake = wake
        self._lock = threading.Lock()
        self._request: HaltRequest | None = None
        self._known = threading.Event()

    def set(self, request: HaltRequest | None) -> None:
        """Records the request (None lifts the halt) and wakes the tick loop when it changed."""
        with self._lock:
            changed = request != self._request
            self._request = request
        self._known.set()
        if changed:
            self._wake()

    def current(self) -> HaltRequest | None:
        with self._lock:
            return self._request

    def wait_known(self, timeout_s: float) -> bool:
        """Waits (bounded) for the first reading, so an executor restarted while its robot is halted
        does not tick once before it learns so; True if it came."""
        return self._known.wait(timeout_s)


def park_builder(document: Any, registry: Any, context: Any) -> ParkBuilder:
    """Builds the tree of one `<BehaviorTree>` of the mission's document, with the mission's
    behaviors and context, for a halt's park tree."""
    from coral_core import bt

    def build(tree_id: str) -> Any:
        if tree_id not in document.trees:
            known = ", ".join(sorted(document.trees))
            raise bt.BTLoadError(f"the tree document defines no BehaviorTree {tree_id!r} ({known} only)")
        park = dataclasses.replace(document, main_tree=tree_id, main_error=None)
        return bt.build_tree(park, registry, context=context)

    return build


@dataclass(frozen=True)
class HaltOutcome:
    """What halting did, as the `halted` record reports it."""

    since: float
    """When the tree stopped ticking (seconds since the epoch)."""
    park_tree: str | None = None
    park_status: ParkStatus | None = None
    error: str = ""
    """What went wrong: a behavior's halt raised, the park tree could not be built (MISSING), or
    one of its behaviors raised."""

    def record_fields(self) -> dict[str, Any]:
        return {"since": self.since, "park_tree": self.park_tree, "park_status": self.park_status}


def halt_tree(
    tree: Any,
    request: HaltRequest,
    build_park: ParkBuilder | None,
    *,
    period_s: float,
    stop: threading.Event,
    clock: Callable[[], float] = time.monotonic,
) -> HaltOutcome:
    """Halts `tree`, then runs the park tree of `request` (bounded by its timeout and by `stop`)."""
    from coral_core import bt

    try:
        tree.halt()
        halt_error = ""
    except Exception as raised:  # noqa: BLE001 - a behavior's on_halted failed; the tree stops all the same
        halt_error = f"halting the tree failed: {raised}"
    since = time.time()
    if request.park_tree is None:
        return HaltOutcome(since=since, error=halt_error)
    try:
        if build_park is None:
            raise bt.BTLoadError("this executor builds no park trees")
        park = build_park(request.park_tree)
    except bt.BTError as error:
        return HaltOutcome(since=since, park_tree=request.park_tree, park_status="MISSING", error=str(error))
    deadline = clock() + request.park_timeout_seconds
    status: ParkStatus = "TIMEOUT"
    error = ""
    try:
        while not stop.is_set() and clock() < deadline:
            started = clock()
            root = park.tick_exactly_once()
            if root in (bt.Status.SUCCESS, bt.Status.FAILURE):
                status = "SUCCESS" if root == bt.Status.SUCCESS else "FAILURE"
                break
            # A wake-up ticks again at once; the period bounds the polling of the others.
            park.wait_for_wake_up(max(0.0, min(deadline, started + period_s) - clock()))
    except bt.BTRuntimeError as raised:  # a behavior raised: the park failed, the halt still holds
        status, error = "FAILURE", str(raised)
    finally:
        park.halt()
    return HaltOutcome(
        since=since,
        park_tree=request.park_tree,
        park_status=status,
        error="; ".join(filter(None, (halt_error, error))),
    )
