"""Remote triggers: early ones wait in the inbox, repeated ones count once, others' are ignored."""

from __future__ import annotations

from coral.coordination import messages
from coral.coordination.inbox import Inbox


def _trigger(message_id: str, target: str = "robot_b", process: str = "go") -> messages.Trigger:
    return messages.Trigger(message_id, "robot_a", target, process)


def test_a_trigger_received_before_anyone_waits_is_kept_until_taken() -> None:
    inbox = Inbox("robot_b")
    assert inbox.accept_trigger(_trigger("1"))
    assert inbox.pending("go") == 1
    assert inbox.take_trigger("go") == "1"
    assert inbox.take_trigger("go") is None


def test_a_repeated_trigger_is_acknowledged_again_but_counted_once() -> None:
    inbox = Inbox("robot_b")
    assert inbox.accept_trigger(_trigger("1"))
    assert inbox.accept_trigger(_trigger("1")), "the sender needs a fresh ack for its resend"
    assert inbox.pending("go") == 1


def test_two_distinct_triggers_count_twice_in_order() -> None:
    inbox = Inbox("robot_b")
    inbox.accept_trigger(_trigger("1"))
    inbox.accept_trigger(_trigger("2"))
    assert [inbox.take_trigger("go"), inbox.take_trigger("go")] == ["1", "2"]


def test_triggers_for_another_host_are_ignored_and_not_acknowledged() -> None:
    inbox = Inbox("robot_b")
    assert not inbox.accept_trigger(_trigger("1", target="robot_c"))
    assert inbox.pending("go") == 0


def test_shared_values_keep_the_newest_per_sender_and_key() -> None:
    inbox = Inbox("robot_b")
    inbox.accept_value(messages.SharedValue("1", "robot_a", "*", "map", "v1", 10.0))
    inbox.accept_value(messages.SharedValue("2", "robot_a", "robot_b", "map", "v2", 11.0))
    inbox.accept_value(messages.SharedValue("3", "robot_c", "*", "map", "c1", 9.0))
    assert not inbox.accept_value(messages.SharedValue("4", "robot_a", "robot_z", "map", "nope", 12.0))
    newest = inbox.value("map")
    assert newest is not None and newest.value == "v2"
    from_c = inbox.value("map", sender="robot_c")
    assert from_c is not None and from_c.value == "c1"
    assert inbox.value("other") is None


def test_messages_round_trip_and_garbage_is_dropped() -> None:
    trigger = _trigger("abc")
    assert messages.decode_trigger(messages.encode(trigger)) == trigger
    assert messages.decode_trigger("{}") is None
    assert messages.decode_ack("[") is None
