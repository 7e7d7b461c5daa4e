"""The instance work queue: one pass per burst, never two at once for a key, failures retried."""

from __future__ import annotations

import threading
import time
from collections import Counter
from collections.abc import Callable

from coral_operator.kube.workqueue import WorkQueue
from coral_testbed.waiting import wait_for


def _wait(condition: Callable[[], object], timeout: float = 5.0) -> None:
    wait_for(condition, timeout=timeout, interval=0.005, message="the work queue to get there")


def test_a_burst_of_adds_for_one_key_costs_one_pass() -> None:
    passes: Counter[str] = Counter()
    queue: WorkQueue[str] = WorkQueue(
        lambda key: passes.update([key]), workers=2, min_interval_s=0.0, name="t"
    )
    # Held back until the burst is in, so the dedup is what keeps it at one pass.
    queue.add("r1", delay_s=0.2)
    for _ in range(50):
        queue.add("r1", delay_s=0.2)
    queue.add("r2", delay_s=0.2)
    queue.start()
    try:
        _wait(lambda: passes["r1"] == 1 and passes["r2"] == 1)
        _wait(lambda: len(queue) == 0)
        assert passes == Counter({"r1": 1, "r2": 1})
    finally:
        queue.stop()


def test_an_add_during_a_pass_runs_one_more_pass_after_it_never_alongside() -> None:
    running = Counter[str]()
    overlap: list[str] = []
    passes: list[str] = []
    entered = threading.Event()
    release = threading.Event()
    lock = threading.Lock()

    def process(key: str) -> None:
        with lock:
            running[key] += 1
            if running[key] > 1:
                overlap.append(key)
        if not passes:
            entered.set()
            release.wait(5)
        passes.append(key)
        with lock:
            running[key] -= 1

    queue: WorkQueue[str] = WorkQueue(process, workers=4, name="t")
    queue.start()
    try:
        queue.add("r1")
        assert entered.wait(5)
        for _ in range(10):
            queue.add("r1")
        release.set()
        _wait(lambda: len(passes) == 2 and len(queue) == 0)
        assert passes == ["r1", "r1"] and overlap == []
    finally:
        queue.stop()


def test_passes_of_one_key_are_spaced_by_the_interval() -> None:
    times: list[float] = []
    queue: WorkQueue[str] = WorkQueue(
        lambda key: times.append(time.monotonic()), workers=2, min_interval_s=0.3
    )
    queue.start()
    try:
        queue.add("r1")
        _wait(lambda: len(times) == 1)
        queue.add("r1")
        _wait(lambda: len(times) == 2)
        assert times[1] - times[0] >= 0.29
    finally:
        queue.stop()


def test_a_failed_pass_is_retried_with_growing_delays_until_it_succeeds() -> None:
    """The failure is raised by the pass itself (an API error cannot be caused on demand here)."""
    times: list[float] = []

    def flaky(key: str) -> None:
        times.append(time.monotonic())
        if len(times) < 3:
            raise RuntimeError("API unavailable")

    queue: WorkQueue[str] = WorkQueue(flaky, workers=1, retry_base_s=0.05, retry_max_s=1.0, name="t")
    queue.start()
    try:
        queue.add("r1")
        _wait(lambda: len(times) == 3)
        first, second = times[1] - times[0], times[2] - times[1]
        assert first >= 0.045 and second >= 0.095, (first, second)
        _wait(lambda: len(queue) == 0)
        assert len(times) == 3, "a successful pass is not retried"
    finally:
        queue.stop()
