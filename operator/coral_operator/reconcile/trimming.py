"""Hands memory back to the system after objects are forgotten.

CPython frees small objects into its own arenas and glibc keeps freed heap pages for reuse, so a
process that held a deleted fleet's records keeps their pages resident: the operator grew 2.85 MB
per robot and did not shrink when the system was deleted (issue 47). After a burst of deletions
the controller (`reconcile.controller`) asks for one trim, run a moment later on a timer thread:
a full collection, then glibc's `malloc_trim`, which returns free heap pages. Elsewhere than
glibc the trim is a collection only.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import gc
import threading
from collections.abc import Callable

# Deletions come in bursts (a system's instances, their pods): one trim after the burst, not one each.
TRIM_DELAY_S = 2.0


def _malloc_trim() -> Callable[[], None]:
    name = ctypes.util.find_library("c")
    try:
        trim = ctypes.CDLL(name).malloc_trim if name else None
    except (OSError, AttributeError):
        trim = None
    if trim is None:
        return lambda: None
    return lambda: trim(0)


class Trimmer:
    """Runs `gc.collect` and `malloc_trim` once, `delay` seconds after the first request of a burst."""

    def __init__(self, delay: float = TRIM_DELAY_S, trim: Callable[[], None] | None = None) -> None:
        self._delay = delay
        self._trim = trim or _malloc_trim()
        self._lock = threading.Lock()
        self._timer: threading.Timer | None = None
        self.runs = 0

    def soon(self) -> None:
        with self._lock:
            if self._timer is not None:
                return
            self._timer = threading.Timer(self._delay, self._run)
            self._timer.daemon = True
            self._timer.name = "coral-trim"
            self._timer.start()

    def _run(self) -> None:
        with self._lock:
            self._timer = None
        gc.collect()
        self._trim()
        self.runs += 1

    def stop(self) -> None:
        with self._lock:
            timer, self._timer = self._timer, None
        if timer is not None:
            timer.cancel()
