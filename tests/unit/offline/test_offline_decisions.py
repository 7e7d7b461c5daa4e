"""What a robot runs at boot, and when its offline copy gives way to the API server's pods."""

from __future__ import annotations

from coral_core import offline
from coral_core.offline import BootAction, HandOver, Verdict

GOOD = Verdict(manifest=object())  # type: ignore[arg-type]
BAD = Verdict(None, "file x was altered")


def test_with_the_api_server_nothing_runs_offline() -> None:
    assert offline.boot_actions(api_reachable=True, verdicts={"a": GOOD, "b": BAD}) == {
        "a": BootAction.ONLINE,
        "b": BootAction.ONLINE,
    }
    assert offline.boot_actions(api_reachable=True, verdicts={}) == {"": BootAction.ONLINE}


def test_offline_only_a_checked_cache_runs() -> None:
    assert offline.boot_actions(api_reachable=False, verdicts={"a": GOOD, "b": BAD}) == {
        "a": BootAction.RUN,
        "b": BootAction.REFUSE,
    }


def test_a_robot_never_given_a_revision_runs_nothing() -> None:
    assert offline.boot_actions(api_reachable=False, verdicts={}) == {"": BootAction.NOTHING}


def test_the_hand_over_waits_for_the_api_server_and_the_update_lock() -> None:
    def decide(reachable: bool, running: bool, interrupt: bool) -> HandOver:
        return offline.hand_over(
            api_reachable=reachable, tree_running=running, interrupt_running_trees=interrupt
        )

    assert decide(False, False, True) == HandOver.KEEP
    assert decide(True, True, False) == HandOver.KEEP
    assert decide(True, True, True) == HandOver.HAND_OVER
    assert decide(True, False, False) == HandOver.HAND_OVER
