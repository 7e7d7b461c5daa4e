"""Waiting for a state that may flip once more before it settles."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from coral_testbed.waiting import WaitTimeout, wait_until_steady


def _answers(*values: bool) -> Iterator[bool]:
    yield from values
    while True:
        yield values[-1]


def test_a_state_that_flips_after_first_holding_is_waited_past() -> None:
    answers = _answers(True, False, True)
    checks: list[bool] = []

    def ready() -> bool:
        checks.append(next(answers))
        return checks[-1]

    wait_until_steady(ready, steady_for=0.2, timeout=5, interval=0.01)
    assert checks[:3] == [True, False, True]
    assert len(checks) > 3


def test_a_state_that_keeps_flipping_times_out_naming_what_was_awaited() -> None:
    state = [False]

    def flapping() -> bool:
        state[0] = not state[0]
        return state[0]

    with pytest.raises(WaitTimeout, match="the system Ready"):
        wait_until_steady(flapping, steady_for=0.2, timeout=0.5, interval=0.01, message="the system Ready")
