"""Times at which the executor must tick although nothing woke its tree: behaviors' deadlines.

Behaviors whose RUNNING state changes only on an event (a service response, a message) wake the
tree when it happens, so the tick loop sleeps in between (`Tree.needs_polling` is False). What
no event announces is a deadline: a call that times out, a service still being discovered. Such
behaviors book the time here (`CallContext.wake_at`) and cancel it when it no longer matters; the
tick loop sleeps until the earliest booked time at the latest. Pure, thread-safe, clock injected.
"""

from __future__ import annotations

import heapq
import itertools
import threading


class WakeSchedule:
    def __init__(self) -> None:
        self._heap: list[tuple[float, int]] = []
        self._live: set[int] = set()
        self._ids = itertools.count()
        self._lock = threading.Lock()

    def add(self, when: float) -> int:
        """Books a tick at monotonic time `when`; returns a token for `cancel`."""
        with self._lock:
            token = next(self._ids)
            heapq.heappush(self._heap, (when, token))
            self._live.add(token)
            return token

    def cancel(self, token: int) -> None:
        with self._lock:
            self._live.discard(token)

    def next_due(self, now: float) -> float | None:
        """The earliest booked time still ahead or just due (times up to `now` are consumed), or
        None. Cancelled bookings are dropped on the way."""
        with self._lock:
            heap = self._heap
            while heap and (heap[0][1] not in self._live or heap[0][0] < now):
                when, token = heapq.heappop(heap)
                if token in self._live:
                    self._live.discard(token)
                    return when  # due now: the caller ticks at once
            return heap[0][0] if heap else None
