"""Executors coordinate through TriggerRemote / WaitForRemoteTrigger and shared values, and fall back
when the peer is absent (acceptance 5)."""

from __future__ import annotations

from pathlib import Path

import pytest
from fixtures.processes import Spawn

from .runtime_processes import finish, read_records, records_of, start_executor, wait_until, write_tree

pytestmark = [pytest.mark.ros, pytest.mark.slow]

SENDER = """
    <Sequence>
      <ShareValue key="survey" value="area_42"/>
      <TriggerRemote remote_hostname="robot_b" process_identifier="go" timeout_ms="30000"/>
    </Sequence>"""

# The second wait must time out: the sender's resends and the replayed history carry one trigger id.
RECEIVER = """
    <Sequence>
      <WaitForRemoteTrigger process_identifier="go" timeout_ms="30000"/>
      <Inverter><WaitForRemoteTrigger process_identifier="go" timeout_ms="1500"/></Inverter>
      <WaitForSharedValue key="survey" value="{survey}" timeout_ms="5000"/>
      <ScriptCondition code="survey == 'area_42'"/>
    </Sequence>"""


def test_a_trigger_sent_before_the_waiter_started_arrives_once(
    tmp_path: Path, ros_env: dict[str, str], spawned: Spawn
) -> None:
    plugins = tmp_path / "plugins"
    plugins.mkdir()
    sender_status = tmp_path / "a.jsonl"
    sender_log = tmp_path / "a.log"
    sender = start_executor(
        spawned,
        ros_env,
        write_tree(tmp_path / "a.xml", SENDER),
        plugins,
        sender_status,
        sender_log,
        "--hostname",
        "robot_a",
        "--name",
        "executor_a",
    )

    def trigger_sent() -> bool:
        return any(
            r["event"] == "transition" and r["node_id"] == "TriggerRemote" and r["status"] == "RUNNING"
            for r in read_records(sender_status)
        )

    wait_until(trigger_sent, 60, "the sender's TriggerRemote to start")
    receiver_status = tmp_path / "b.jsonl"
    receiver_log = tmp_path / "b.log"
    receiver = start_executor(
        spawned,
        ros_env,
        write_tree(tmp_path / "b.xml", RECEIVER),
        plugins,
        receiver_status,
        receiver_log,
        "--hostname",
        "robot_b",
        "--name",
        "executor_b",
    )
    assert finish(sender, 60, sender_log) == 0, sender_log.read_text()
    assert finish(receiver, 60, receiver_log) == 0, receiver_log.read_text()


def test_with_the_peer_absent_both_waits_time_out_and_the_fallbacks_run(
    tmp_path: Path, ros_env: dict[str, str], spawned: Spawn
) -> None:
    plugins = tmp_path / "plugins"
    plugins.mkdir()
    tree = write_tree(
        tmp_path / "tree.xml",
        """
    <Sequence>
      <Fallback>
        <TriggerRemote remote_hostname="ghost" process_identifier="go" timeout_ms="1000"/>
        <AlwaysSuccess name="trigger_fallback"/>
      </Fallback>
      <Fallback>
        <WaitForRemoteTrigger process_identifier="never" timeout_ms="1000"/>
        <AlwaysSuccess name="wait_fallback"/>
      </Fallback>
    </Sequence>""",
    )
    status = tmp_path / "status.jsonl"
    log = tmp_path / "executor.log"
    executor = start_executor(spawned, ros_env, tree, plugins, status, log, "--hostname", "robot_a")
    assert finish(executor, 60, log) == 0, log.read_text()
    transitions = records_of(status, "transition")
    failed = {t["node_id"] for t in transitions if t["status"] == "FAILURE"}
    assert failed == {"TriggerRemote", "WaitForRemoteTrigger"}
    fallbacks = [t for t in transitions if t["node_id"] == "AlwaysSuccess" and t["status"] == "SUCCESS"]
    assert len(fallbacks) == 2
