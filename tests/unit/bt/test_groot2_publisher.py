"""The Groot2 publisher's own rules, beyond what the differential against BT.CPP 4.8.2 covers:
safe by default (loopback, hooks refused), 4.10's post-tick hooks and error replies, a new UUID
per tree, the wait for a debugger, and `coral tree watch` reading it."""

from __future__ import annotations

import json
import threading
import time

import pytest
import zmq
from bt_stubs import F, R, S, make_tree
from coral_core.bt.groot2 import protocol as p
from coral_core.bt.groot2.client import Groot2Client, Groot2Error
from groot2_stubs import publish

BODY = '<Sequence name="top"><Q name="a"/><Q name="b"/></Sequence>'


def test_the_publisher_binds_the_loopback_only_by_default() -> None:
    tree, _ = make_tree(BODY, {"a": [S], "b": [S]})
    with publish(tree) as publisher:
        endpoint = publisher._server.getsockopt(zmq.LAST_ENDPOINT).decode()
        assert endpoint.startswith("tcp://127.0.0.1:")


def test_each_published_tree_gets_its_own_uuid() -> None:
    uuids = set()
    for _ in range(2):
        tree, _ = make_tree(BODY, {"a": [S], "b": [S]})
        with publish(tree) as publisher, Groot2Client(port=publisher.port) as client:
            client.status()
            uuids.add(client.tree_uuid)
            assert client.tree_uuid == publisher.tree_uuid and len(client.tree_uuid) == 16
            assert client.tree_uuid[6] >> 4 == 4, "a version 4 UUID, as BT.CPP makes"
    assert len(uuids) == 2


@pytest.mark.parametrize(
    "kind,payload",
    [
        (p.HOOK_INSERT, p.HookRecord(uid=2, mode=p.REPLACE, desired_status=3).as_json()),
        (p.BREAKPOINT_UNLOCK, {"uid": 2, "desired_status": "SUCCESS", "position": 0, "remove_when_done": 1}),
    ],
)
def test_hooks_that_change_the_tree_are_refused_unless_allowed(kind: int, payload: dict) -> None:
    tree, _ = make_tree(BODY, {"a": [S], "b": [S]})
    with publish(tree) as publisher, Groot2Client(port=publisher.port) as client:
        with pytest.raises(Groot2Error, match="hooks are disabled"):
            client.request(kind, json.dumps(payload).encode())
        assert client.hooks() == []
        assert tree.tick_exactly_once() == S, "the tree is untouched"


def test_a_post_tick_hook_replaces_the_result_after_the_tick_as_in_bt_cpp_4_10() -> None:
    # BT.CPP 4.8.2 installs a post hook before the tick; 4.10 after it, with the tick's result.
    tree, queues = make_tree(BODY, {"a": [S], "b": [S]})
    with publish(tree, allow_hooks=True) as publisher, Groot2Client(port=publisher.port) as client:
        client.insert_hooks([p.HookRecord(uid=2, position=p.POST, mode=p.REPLACE, desired_status=3)])
        assert [h["position"] for h in client.hooks()] == [p.POST], "4.10 dumps post hooks too"
        assert tree.tick_exactly_once() == F
        assert queues.calls == {"a": 1}, "the node ran, then its result was replaced"
        client.remove_hook(2, p.POST)
        assert tree.tick_exactly_once() == S


def test_a_post_tick_breakpoint_holds_after_the_tick_until_unlocked() -> None:
    tree, queues = make_tree(BODY, {"a": [S], "b": [S]})
    with publish(tree, allow_hooks=True) as publisher, Groot2Client(port=publisher.port) as client:
        client.next_breakpoint(0)
        time.sleep(0.1)
        client.insert_hooks([p.HookRecord(uid=3, position=p.POST)])
        result: list[int] = []
        ticking = threading.Thread(target=lambda: result.append(tree.tick_exactly_once()))
        ticking.start()
        assert client.next_breakpoint(5) == 3
        assert queues.calls == {"a": 1, "b": 1} and client.status()[3] == 0, "ticked, not yet set"
        client.unlock(3, "FAILURE", p.POST)
        ticking.join(5)
        assert result == [F]


def test_malformed_hook_requests_get_error_replies_as_in_bt_cpp_4_10() -> None:
    tree, _ = make_tree(BODY, {"a": [S], "b": [S]})
    with publish(tree, allow_hooks=True) as publisher, Groot2Client(port=publisher.port) as client:
        for payload in (b"{", b'{"uid": 2}', b'{"uid": "2", "position": 0}', b"[1]", b"\xff"):
            with pytest.raises(Groot2Error):
                client.request(p.HOOK_INSERT, payload)
        with pytest.raises(Groot2Error, match="Node ID not found"):
            client.unlock(99, "SUCCESS")
        with pytest.raises(Groot2Error, match="Node ID not found"):
            client.remove_hook(2)
        assert client.hooks() == []
        assert tree.tick_exactly_once() == S


def test_wait_for_client_holds_until_a_hook_is_set_or_a_watching_client_had_its_grace() -> None:
    tree, _ = make_tree(BODY, {"a": [R], "b": [S]})
    with publish(tree, allow_hooks=True) as publisher:
        started = time.monotonic()
        assert publisher.wait_for_client(0.2) is False, "nobody came"
        assert 0.15 < time.monotonic() - started < 2
        with Groot2Client(port=publisher.port) as client:
            client.status()
            started = time.monotonic()
            assert publisher.wait_for_client(5, grace_s=0.3) is True, "a client that only watches"
            assert 0.2 < time.monotonic() - started < 2
    tree, _ = make_tree(BODY, {"a": [R], "b": [S]})
    with publish(tree, allow_hooks=True) as publisher, Groot2Client(port=publisher.port) as client:
        asking = threading.Timer(0.2, lambda: client.insert_hooks([p.HookRecord(uid=3)]))
        asking.start()
        started = time.monotonic()
        assert publisher.wait_for_client(30, grace_s=30) is True
        assert time.monotonic() - started < 5, "the hook ended the wait"
        asking.join(5)


def test_closing_the_publisher_releases_a_held_breakpoint() -> None:
    tree, _ = make_tree(BODY, {"a": [S], "b": [S]})
    publisher = publish(tree, allow_hooks=True)
    with Groot2Client(port=publisher.port) as client:
        client.insert_hooks([p.HookRecord(uid=2)])
        ticking = threading.Thread(target=tree.tick_exactly_once)
        ticking.start()
        time.sleep(0.2)
        assert ticking.is_alive(), "held at the breakpoint"
        publisher.close()
        ticking.join(5)
        assert not ticking.is_alive()
