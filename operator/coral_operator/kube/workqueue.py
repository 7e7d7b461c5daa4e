"""A keyed work queue with a few worker threads, the way Kubernetes' own controllers are built.

Watch events only name the object that needs a pass (`add`); the workers run the pass later from
the caches. A key is held at most once however many events name it, never processed by two
workers at once (an `add` during its pass queues one more pass afterwards), and passes of one key
are spaced by `min_interval_s` (a number, or a function of the key), so a burst of events (a pod
created, bound, started) costs one pass and one status write instead of one per event. A delayed
`add` stands in for a timer. A failed pass is retried with a per-key
exponential backoff. Memory is bounded by the number of distinct keys.
"""

from __future__ import annotations

import contextvars
import heapq
import logging
import threading
import time
from collections.abc import Callable, Hashable
from typing import Generic, TypeVar

K = TypeVar("K", bound=Hashable)
LOG = logging.getLogger(__name__)
# How often the queue logs what it did (passes, time spent in them, how late they started): at
# fleet scale the line tells whether passes wait for a worker or for the API.
REPORT_INTERVAL_S = 10.0


class _Tally:
    """Passes since the last report: how many, how long they ran and how late they started."""

    def __init__(self) -> None:
        self.since = time.monotonic()
        self.passes = 0
        self.busy = 0.0
        self.late = 0.0
        self.latest = 0.0

    def add(self, late: float, busy: float) -> None:
        self.passes += 1
        self.busy += busy
        self.late += late
        self.latest = max(self.latest, late)


class WorkQueue(Generic[K]):
    """Deduplicating, delaying, rate-limited queue of keys processed by `workers` threads."""

    def __init__(
        self,
        process: Callable[[K], None],
        *,
        workers: int = 8,
        min_interval_s: float | Callable[[K], float] = 0.0,
        retry_base_s: float = 0.5,
        retry_max_s: float = 30.0,
        name: str = "work",
        on_pass: Callable[[K, bool, float, float], None] | None = None,
    ) -> None:
        """`on_pass(key, failed, late_s, busy_s)` is told of every pass as it ends (metrics)."""
        self._process = process
        self._on_pass = on_pass
        self._workers = workers
        # One queue serves several kinds of key, each spaced as its passes cost.
        self._min_interval: Callable[[K], float] = (
            min_interval_s if callable(min_interval_s) else (lambda _key: float(min_interval_s))
        )
        self._retry_base = retry_base_s
        self._retry_max = retry_max_s
        self._name = name
        self._cond = threading.Condition()
        # Keys due at a time (heap of (due, sequence, key)); `_due` is each key's earliest due time.
        self._heap: list[tuple[float, int, K]] = []
        self._due: dict[K, float] = {}
        self._sequence = 0
        self._processing: set[K] = set()
        self._again: dict[K, float] = {}
        self._last_run: dict[K, float] = {}
        self._failures: dict[K, int] = {}
        self._threads: list[threading.Thread] = []
        self._stopping = False
        self._tally = _Tally()

    def start(self) -> None:
        """Start the workers, each in a copy of the caller's context variables.

        Threads start with an empty context otherwise; a framework that keeps its state there
        (kopf's event poster, say) is reachable from the passes only this way.
        """
        self._stopping = False
        for index in range(self._workers):
            context = contextvars.copy_context()
            thread = threading.Thread(
                target=context.run, args=(self._loop,), name=f"{self._name}-{index}", daemon=True
            )
            thread.start()
            self._threads.append(thread)

    def ensure_started(self) -> None:
        """Start the workers unless they run already (see `start` for the context they get)."""
        with self._cond:
            if self._threads:
                return
            self.start()

    def stop(self, timeout: float = 5.0) -> None:
        with self._cond:
            self._stopping = True
            self._cond.notify_all()
        for thread in self._threads:
            thread.join(timeout)
        self._threads.clear()

    def add(self, key: K, delay_s: float = 0.0) -> None:
        """Ask for a pass of `key` no sooner than `delay_s` from now (and its rate limit)."""
        now = time.monotonic()
        due = max(now + delay_s, self._last_run.get(key, -1e18) + self._min_interval(key))
        with self._cond:
            if key in self._processing:
                # Queued again once the running pass ends, so the pass sees this event's cause.
                self._again[key] = min(self._again.get(key, due), due)
                return
            current = self._due.get(key)
            if current is not None and current <= due:
                return
            self._due[key] = due
            self._sequence += 1
            heapq.heappush(self._heap, (due, self._sequence, key))
            self._cond.notify()

    def forget(self, key: K) -> None:
        """Drop what is remembered of a key whose object is gone."""
        with self._cond:
            self._last_run.pop(key, None)
            self._failures.pop(key, None)

    def pending(self) -> set[K]:
        """The keys waiting for a pass (not those being processed)."""
        with self._cond:
            return set(self._due)

    def __len__(self) -> int:
        with self._cond:
            return len(self._due) + len(self._processing)

    def longest_wait_s(self) -> float:
        """How long the most overdue key has been due without a worker taking it (0 if none)."""
        with self._cond:
            earliest = min(self._due.values(), default=None)
        return 0.0 if earliest is None else max(0.0, time.monotonic() - earliest)

    def _take(self) -> tuple[K, float] | None:
        """The next due key and how late it is taken (waiting for a free worker), or None to stop."""
        with self._cond:
            while not self._stopping:
                while self._heap and self._due.get(self._heap[0][2]) != self._heap[0][0]:
                    heapq.heappop(self._heap)  # superseded by an earlier due time
                if self._heap:
                    due, _, key = self._heap[0]
                    wait = due - time.monotonic()
                    if wait <= 0:
                        heapq.heappop(self._heap)
                        del self._due[key]
                        self._processing.add(key)
                        return key, -wait
                    self._cond.wait(wait)
                else:
                    self._cond.wait()
            return None

    def _done(self, key: K, failed: bool, late: float, busy: float) -> None:
        if self._on_pass is not None:
            self._on_pass(key, failed, late, busy)
        now = time.monotonic()
        self._last_run[key] = now
        if failed:
            count = self._failures.get(key, 0) + 1
            self._failures[key] = count
            retry = min(self._retry_base * 2 ** (count - 1), self._retry_max)
        else:
            self._failures.pop(key, None)
            retry = None
        with self._cond:
            self._processing.discard(key)
            again = self._again.pop(key, None)
            self._tally.add(late, busy)
            report, depth = None, len(self._due)
            if now - self._tally.since >= REPORT_INTERVAL_S:
                report, self._tally = self._tally, _Tally()
        if report is not None:
            LOG.info(
                "%s: %d passes in %.0f s, %.1f s of them in passes, started %.0f ms late on average "
                "(at most %.0f ms); %d due",
                self._name,
                report.passes,
                now - report.since,
                report.busy,
                report.late / report.passes * 1000,
                report.latest * 1000,
                depth,
            )
        if retry is not None:
            self.add(key, retry)
        elif again is not None:
            self.add(key, max(again - now, 0.0))

    def _loop(self) -> None:
        while True:
            taken = self._take()
            if taken is None:
                return
            key, late = taken
            failed = False
            began = time.monotonic()
            try:
                self._process(key)
            except Exception:
                failed = True
                LOG.exception("%s pass for %s failed; retrying with backoff", self._name, key)
            self._done(key, failed, late, time.monotonic() - began)
