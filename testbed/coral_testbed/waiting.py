"""Polling with a deadline: the one way tests and tooling wait for the world to change.

Used by the local control plane (component health), the cluster fixture and every integration test
that waits for an object to reach a state. Nothing here sleeps to synchronize: it re-checks a
condition until it holds or the deadline passes, and then says what it was waiting for.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TypeVar

T = TypeVar("T")


class WaitTimeout(TimeoutError):
    """A condition did not hold before its deadline; the message says which and what was last seen."""


def wait_for(
    predicate: Callable[[], T],
    timeout: float,
    interval: float = 0.2,
    message: str | Callable[[], str] = "condition",
) -> T:
    """Calls `predicate` until it returns something truthy, and returns that value.

    Args:
        predicate: checked repeatedly; exceptions it raises propagate (a broken check is not a
            slow one), so catch expected "not yet" errors inside it.
        timeout: seconds before giving up.
        interval: seconds between checks.
        message: what was awaited, or a callable producing it at timeout (to include the last
            observed state).

    Raises:
        WaitTimeout: the predicate stayed falsy for `timeout` seconds.
    """
    deadline = time.monotonic() + timeout
    while True:
        result = predicate()
        if result:
            return result
        remaining = deadline - time.monotonic()
        if remaining <= 0:
            text = message() if callable(message) else message
            raise WaitTimeout(f"timed out after {timeout:g} s waiting for {text}")
        time.sleep(min(interval, remaining))


def holds_for(
    predicate: Callable[[], bool],
    duration: float,
    interval: float = 0.5,
    message: str | Callable[[], str] = "condition",
) -> None:
    """Checks that `predicate` stays true for `duration` seconds (an "it did not happen" assertion).

    Raises:
        AssertionError: the predicate became false; the message says when.
    """
    start = time.monotonic()
    deadline = start + duration
    while True:
        if not predicate():
            text = message() if callable(message) else message
            raise AssertionError(f"{text} stopped holding after {time.monotonic() - start:.1f} s")
        remaining = deadline - time.monotonic()
        if remaining <= 0:
            return
        time.sleep(min(interval, remaining))
