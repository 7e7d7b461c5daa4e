"""SIGINT and SIGTERM handled on a thread of their own, where the handler may take locks.

Python runs a signal handler on the main thread, between two of its bytecodes, so possibly while
that thread holds the lock of the very Event or Condition the handler would set (inside
`Event.wait`, say). Both locks are plain ones: a handler that sets such an Event waits for itself
forever, and the process no longer stops on a signal. An executor once hung so after SIGINT
while it waited for its tree's next wake-up.

So the handler installed here only writes the signal's number into a pipe, which takes no Python
lock; a daemon thread reads the pipe and calls the callback, which may then set events, wake
conditions and log like any other thread.
"""

from __future__ import annotations

import os
import signal
import threading
from collections.abc import Callable
from types import FrameType

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


def relay_stop_signals(callback: Callable[[int], None]) -> None:
    """From now on each SIGINT or SIGTERM calls `callback(signum)` on the relay thread, in order.

    Call it from the main thread (only it may install handlers).
    """
    read_end, write_end = os.pipe()
    # A full pipe (thousands of signals nobody reads yet) must drop a signal, not block the handler.
    os.set_blocking(write_end, False)

    def handle(signum: int, _frame: FrameType | None) -> None:
        try:
            os.write(write_end, bytes([signum]))
        except BlockingIOError:
            pass

    def relay() -> None:
        while data := os.read(read_end, 64):
            for signum in data:
                callback(signum)

    threading.Thread(target=relay, name="stop-signals", daemon=True).start()
    for signum in STOP_SIGNALS:
        signal.signal(signum, handle)
