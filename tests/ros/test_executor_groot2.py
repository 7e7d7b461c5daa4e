"""An executor started with `--groot2-port`, `--groot2-wait` and `--groot2-allow-hooks` holds its
first tick until a Groot2 client connects, publishes its tree, holds a breakpoint the client set
before the mission started, and goes on with the result the client chose (issue 49)."""

from __future__ import annotations

import random
import signal
import time
from pathlib import Path

import pytest
from coral_core.bt.groot2 import protocol as p
from coral_core.bt.groot2.client import Groot2Client, Groot2Error
from fixtures.ports import free_port_pair
from fixtures.processes import Spawn

from .runtime_processes import finish, records_of, start_executor, wait_until, write_tree

pytestmark = [pytest.mark.ros, pytest.mark.slow]

# uids: 1 Sequence, 2 Script, 3 Sleep, 4 Script.
TREE = """
    <Sequence name="mission">
      <Script code="n := 1"/>
      <Sleep msec="100"/>
      <Script name="second" code="n := 2"/>
    </Sequence>
"""


def _answering(client: Groot2Client) -> bool:
    try:
        client.hooks()
        return True
    except Groot2Error:
        return False


def test_a_breakpoint_set_before_the_first_tick_holds_the_mission_until_unlocked(
    tmp_path: Path, ros_env: dict[str, str], spawned: Spawn
) -> None:
    port = free_port_pair(random.randrange(50000, 60000, 2))
    tree = write_tree(tmp_path / "tree.xml", TREE)
    status, log = tmp_path / "status.jsonl", tmp_path / "executor.log"
    (tmp_path / "plugins").mkdir()
    args = ("--groot2-port", str(port), "--groot2-wait", "60", "--groot2-allow-hooks", "--liveness-wait", "0")
    executor = start_executor(spawned, ros_env, tree, tmp_path / "plugins", status, log, *args)
    with Groot2Client(port=port, timeout_s=1) as client:
        client.next_breakpoint(0)  # subscribed before anything is announced
        wait_until(lambda: _answering(client) or executor.poll() is not None, 60, "the publisher")
        assert executor.poll() is None, log.read_text()
        time.sleep(0.5)
        assert client.status() == {1: 0, 2: 0, 3: 0, 4: 0}, "nothing ticks before the client set a hook"
        client.insert_hooks([p.HookRecord(uid=4)])
        assert client.next_breakpoint(30) == 4, log.read_text()
        held = client.status()
        assert (held[1], held[2], held[3]) == (1, 2, 2), "the mission waits at the breakpoint"
        assert client.blackboards(["Main"]) == {"Main": {"n": 1}}
        time.sleep(0.3)
        assert executor.poll() is None and client.status()[4] == 0, "still held"
        client.unlock(4, "SUCCESS")  # the node is not ticked: n stays 1
    assert finish(executor, 60, log) == 0, log.read_text()
    [announced, waited] = records_of(status, "groot2")
    assert announced["port"] == port and announced["hooks"] is True and announced["host"] == "127.0.0.1"
    assert waited["client_connected"] is True
    [finished] = records_of(status, "finished")
    assert finished["root_status"] == "SUCCESS"


def test_a_stop_signal_releases_a_held_breakpoint_and_the_executor_halts(
    tmp_path: Path, ros_env: dict[str, str], spawned: Spawn
) -> None:
    port = free_port_pair(random.randrange(50000, 60000, 2))
    # A long Sleep after the breakpoint: the released tick leaves the tree RUNNING, then the stop halts it.
    tree = write_tree(tmp_path / "tree.xml", TREE.replace("</Sequence>", '<Sleep msec="60000"/></Sequence>'))
    status, log = tmp_path / "status.jsonl", tmp_path / "executor.log"
    (tmp_path / "plugins").mkdir()
    args = ("--groot2-port", str(port), "--groot2-wait", "60", "--groot2-allow-hooks", "--liveness-wait", "0")
    executor = start_executor(spawned, ros_env, tree, tmp_path / "plugins", status, log, *args)
    with Groot2Client(port=port, timeout_s=1) as client:
        client.next_breakpoint(0)
        wait_until(lambda: _answering(client) or executor.poll() is not None, 60, "the publisher")
        client.insert_hooks([p.HookRecord(uid=4)])
        assert client.next_breakpoint(30) == 4, log.read_text()
        executor.send_signal(signal.SIGTERM)
        # The client stays connected (its heartbeat would keep the breakpoint): the stop releases it.
        deadline = time.monotonic() + 20
        while executor.poll() is None and time.monotonic() < deadline:
            try:
                client.status()
            except Groot2Error:
                pass
            time.sleep(0.1)
    assert finish(executor, 10, log) == 128 + signal.SIGTERM, log.read_text()
