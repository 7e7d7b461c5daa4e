"""Polling with a deadline: the one way tests and tooling wait for the world to change.

Used by the local control plane (component health), the cluster fixture and every integration test
that waits for an object to reach a state. Nothing here sleeps to synchronize: it re-checks a
condition until it holds or the deadline passes, and then says what it was waiting for. tenacity
does the re-checking; this module adds the deadline message and the "it stays true" check.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import NoReturn, TypeVar

import tenacity

T = TypeVar("T")


class WaitTimeout(TimeoutError):
    """A condition did not hold before its deadline; the message says which and what was last seen."""


def _until(deadline_s: float, interval: float) -> Callable[[tenacity.RetryCallState], float]:
    """tenacity's pause between checks: `interval`, shortened so that the last check falls on the
    deadline rather than up to one interval after it."""
    return lambda state: max(0.0, min(interval, deadline_s - state.seconds_since_start))


def wait_for(
    predicate: Callable[[], T],
    timeout: float,
    interval: float = 0.2,
    message: str | Callable[[], str] = "condition",
) -> T:
    """Calls `predicate` until it returns something truthy, and returns that value.

    tenacity does the retrying: `predicate` is checked again every `interval` until the deadline.

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

    def timed_out(state: tenacity.RetryCallState) -> NoReturn:
        text = message() if callable(message) else message
        raise WaitTimeout(f"timed out after {timeout:g} s waiting for {text}")

    retrying = tenacity.Retrying(
        retry=tenacity.retry_if_result(lambda result: not result),
        stop=tenacity.stop_after_delay(timeout),
        wait=_until(timeout, interval),
        retry_error_callback=timed_out,
    )
    return retrying(predicate)


def wait_until_steady(
    predicate: Callable[[], bool],
    steady_for: float,
    timeout: float,
    interval: float = 0.2,
    message: str | Callable[[], str] = "condition",
) -> None:
    """Waits until `predicate` has held on every check for `steady_for` seconds in a row.

    For states a controller may leave for a moment before it settles: a watch event still on its
    way can flip the state once more after the first check that sees it hold.

    Raises:
        WaitTimeout: the predicate did not hold for `steady_for` seconds before `timeout`.
    """
    held_since: float | None = None

    def steady() -> bool:
        nonlocal held_since
        now = time.monotonic()
        if not predicate():
            held_since = None
            return False
        if held_since is None:
            held_since = now
        return now - held_since >= steady_for

    wait_for(steady, timeout=timeout, interval=interval, message=message)


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
    retrying = tenacity.Retrying(
        retry=tenacity.retry_if_result(bool),
        stop=tenacity.stop_after_delay(duration),
        wait=_until(duration, interval),
        retry_error_callback=lambda state: True,
    )
    if not retrying(predicate):
        text = message() if callable(message) else message
        raise AssertionError(f"{text} stopped holding after {time.monotonic() - start:.1f} s")
