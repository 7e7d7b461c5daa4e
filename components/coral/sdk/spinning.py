"""An rclpy executor spun on a thread of its own until told to stop, with no wake-up of its own.

A loop of `spin_once(timeout_sec=0.1)` wakes ten times a second to check a stop flag. Each of
those wake-ups rebuilds the executor's wait set in Python, so an idle component cost about 10 ms
of CPU a second, and on a robot computer busy with a parallel registration every interruption
costs the registration more than its own CPU (docs/architecture.md, "Where the SLAM mission's CPU
goes"). `Spinner` waits on rclpy's own condition instead: `spin_until_future_complete` returns as
soon as its future is done, which `stop` does from any thread.

rclpy hangs a "wake the executor" callback on that future at every turn of the loop, two per
callback run, and a future keeps its callbacks until it is done: a component running for days
would hold millions of them. The spinner's future keeps the first one only (`_StopFuture`).

Not for rclpy's EventsExecutor: in Jazzy it does not wake when a future is completed from another
thread (`coral.sdk.streams` polls it, which costs no Python wait set).
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any


def _stop_future() -> Any:
    from rclpy.task import Future

    class _StopFuture(Future):
        """A future that keeps only its first done-callback: every later one rclpy adds while
        spinning is the same wake-up of the same executor."""

        def __init__(self) -> None:
            super().__init__()
            self._has_callback = False

        def add_done_callback(self, callback: Callable[[Any], None]) -> None:
            if self._has_callback:
                return
            self._has_callback = True
            super().add_done_callback(callback)

    return _StopFuture()


class Spinner:
    """Spins `executor` on a daemon thread named `name` until `stop`. An exception raised by a
    callback ends the spinning; it is kept in `error` and `on_error` is called from that thread."""

    def __init__(self, executor: Any, name: str, on_error: Callable[[], None] = lambda: None) -> None:
        self._executor = executor
        self._done = _stop_future()
        self._on_error = on_error
        self.error: BaseException | None = None
        self._thread = threading.Thread(target=self._spin, name=name, daemon=True)

    def start(self) -> Spinner:
        self._thread.start()
        return self

    def _spin(self) -> None:
        from rclpy.executors import ExternalShutdownException

        try:
            self._executor.spin_until_future_complete(self._done)
        except ExternalShutdownException:
            pass
        except Exception as err:  # noqa: BLE001 - handed to the owner, which decides the exit
            self.error = err
            self._on_error()

    def stop(self, timeout_s: float = 2.0) -> None:
        """Ends the spinning (callbacks already running finish on their own threads) and joins."""
        if not self._done.done():
            self._done.set_result(None)
        self._thread.join(timeout=timeout_s)
