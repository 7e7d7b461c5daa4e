"""Waiting for a condition with a deadline, on tenacity: how `coral run -d` and `coral stop` wait.

The supervisor's own loops (`coral.local.supervising`) are not this: they watch several things at
once (signals, exits, readiness) and react to each, rather than waiting for one condition.
"""

from __future__ import annotations

from collections.abc import Callable

import tenacity


def poll_until(condition: Callable[[], bool], timeout_s: float, interval_s: float) -> bool:
    """Calls `condition` every `interval_s` until it returns True (then True) or `timeout_s` passes
    (then False); an exception it raises ends the wait and propagates."""
    retrying = tenacity.Retrying(
        retry=tenacity.retry_if_result(lambda done: not done),
        stop=tenacity.stop_after_delay(timeout_s),
        wait=tenacity.wait_fixed(interval_s),
    )
    try:
        return bool(retrying(condition))
    except tenacity.RetryError:
        return False
