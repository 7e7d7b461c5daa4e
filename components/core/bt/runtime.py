"""Per-tree runtime shared by all nodes: wake-up signal, transition observer, timers, enums, context.

Created by `Tree`; nodes reach it as `self.rt`. `wake_up()` is thread-safe (timer threads and
executor threads call it).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Mapping
from typing import Any


class Timer:
    """One-shot timer on the wall clock; the callback runs under the tree lock unless cancelled."""

    def __init__(self, runtime: Runtime, delay_s: float, callback: Callable[[], None]) -> None:
        self._runtime = runtime
        self._callback = callback
        self.cancelled = False
        self._thread = threading.Timer(max(delay_s, 0.0), self._fire)
        self._thread.daemon = True
        self._thread.start()

    def _fire(self) -> None:
        with self._runtime.lock:
            if self.cancelled:
                return
            self._callback()

    def cancel(self) -> None:
        self.cancelled = True
        self._thread.cancel()


class Runtime:
    def __init__(
        self, enums: Mapping[str, int], context: object = None, clock: Callable[[], float] | None = None
    ) -> None:
        self.enums = enums
        self.context = context
        # Timestamps of transitions; injectable so tests and replays control time.
        self.clock = clock or time.time
        self.lock = threading.RLock()
        self.observer: Callable[[Any, int, int], None] | None = None
        self._wake = threading.Condition(threading.Lock())
        self._woken = False

    def wake_up(self) -> None:
        with self._wake:
            self._woken = True
            self._wake.notify_all()

    def consume_wake_up(self, timeout_s: float = 0.0) -> bool:
        """True if a wake-up was signalled (waiting up to timeout_s); the signal is consumed."""
        with self._wake:
            if not self._woken and timeout_s > 0:
                self._wake.wait_for(lambda: self._woken, timeout=timeout_s)
            woken = self._woken
            self._woken = False
            return woken

    def add_timer(self, delay_s: float, callback: Callable[[], None]) -> Timer:
        return Timer(self, delay_s, callback)
