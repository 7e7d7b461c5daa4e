"""An executor that has never seen a skillset's behaviors runs a tree using them (acceptance 1, 2):
a synchronous action, a service-backed asynchronous action, a condition, and a topic wait."""

from __future__ import annotations

import signal
from pathlib import Path

import pytest
from fixtures.processes import Spawn

from .runtime_processes import (
    finish,
    records_of,
    start_executor,
    start_skillset,
    wait_until,
    write_tree,
)

pytestmark = [pytest.mark.ros, pytest.mark.slow]

TREE = """
    <Sequence>
      <Greet who="robot" greeting="{greeting}"/>
      <Count count="{count}"/>
      <Count count="{count}"/>
      <IsAtLeast value="{count}" threshold="2"/>
      <WaitForCount threshold="2"/>
    </Sequence>
"""


def test_a_tree_of_exported_sync_async_and_condition_behaviors_succeeds(
    tmp_path: Path, ros_env: dict[str, str], spawned: Spawn
) -> None:
    plugins = tmp_path / "plugins"
    start_skillset(spawned, ros_env, plugins, tmp_path / "skillset.log")
    tree = write_tree(tmp_path / "tree.xml", TREE)
    status = tmp_path / "status.jsonl"
    log = tmp_path / "executor.log"
    executor = start_executor(spawned, ros_env, tree, plugins, status, log)
    assert finish(executor, 60, log) == 0, log.read_text()
    [loaded] = records_of(status, "plugins")[-1]["loaded"]
    assert loaded == {"component": "examples", "behaviors": ["Count", "Greet", "IsAtLeast", "WaitForCount"]}
    transitions = records_of(status, "transition")
    count_runs = [t for t in transitions if t["node_id"] == "Count" and t["status"] == "RUNNING"]
    assert len(count_runs) == 2, "Count is asynchronous: it went through RUNNING on each call"
    [finished] = records_of(status, "finished")
    assert (finished["root_status"], finished["exit_code"]) == ("SUCCESS", 0)
    final = records_of(status, "status")[-1]
    assert final["root_status"] == "SUCCESS" and final["last_failure"] is None
    assert {(c["type"], c["status"]) for c in final["conditions"]} == {
        ("PluginsReady", "True"),
        ("LibraryDegraded", "False"),
    }


def test_the_executor_waits_for_a_late_skillset_and_names_what_is_missing(
    tmp_path: Path, ros_env: dict[str, str], spawned: Spawn
) -> None:
    plugins = tmp_path / "plugins"
    plugins.mkdir()
    tree = write_tree(tmp_path / "tree.xml", TREE)
    status = tmp_path / "status.jsonl"
    log = tmp_path / "executor.log"
    executor = start_executor(spawned, ros_env, tree, plugins, status, log)
    waiting = wait_until(lambda: records_of(status, "waiting"), 60, "the executor's waiting record")
    assert waiting[0]["missing"] == ["Count", "Greet", "IsAtLeast", "WaitForCount"]
    assert executor.poll() is None, "the executor keeps waiting instead of failing"
    start_skillset(spawned, ros_env, plugins, tmp_path / "skillset.log")
    assert finish(executor, 60, log) == 0, log.read_text()
    ready = [r for r in records_of(status, "condition") if r["type"] == "PluginsReady"]
    assert [r["status"] for r in ready] == ["False", "True"]
    assert "Waiting for node types: Count, Greet, IsAtLeast, WaitForCount" in log.read_text()


def test_the_executor_opens_its_service_clients_with_the_tree_before_the_first_call(
    tmp_path: Path, ros_env: dict[str, str], spawned: Spawn
) -> None:
    """Discovering a service takes a new client about a tenth of a second: opened at the first
    call, that wait would land in the middle of the mission, so the clients exist from the start."""
    import rclpy
    from rclpy.context import Context

    plugins = tmp_path / "plugins"
    start_skillset(spawned, ros_env, plugins, tmp_path / "skillset.log")
    body = '    <Sequence>\n      <Sleep msec="600000"/>\n      <Count count="{count}"/>\n    </Sequence>'
    tree = write_tree(tmp_path / "tree.xml", body)
    status = tmp_path / "status.jsonl"
    log = tmp_path / "executor.log"
    executor = start_executor(spawned, ros_env, tree, plugins, status, log)

    def sleeping() -> bool:
        return any(t["node_id"] == "Sleep" for t in records_of(status, "transition"))

    wait_until(sleeping, 60, "the Sleep to start")
    context = Context()
    rclpy.init(context=context)
    try:
        graph = rclpy.create_node("graph_reader", context=context)

        def executor_clients() -> set[str]:
            try:
                return {name for name, _ in graph.get_client_names_and_types_by_node("coral_executor", "/")}
            except rclpy.node.NodeNameNonExistentError:
                return set()

        wait_until(lambda: "/examples/count" in executor_clients(), 30, "the executor's client of ~/count")
        graph.destroy_node()
    finally:
        rclpy.shutdown(context=context)
    assert not [t for t in records_of(status, "transition") if t["node_id"] == "Count"], "Count never ran"
    executor.send_signal(signal.SIGINT)
    assert finish(executor, 30, log) == 128 + signal.SIGINT, log.read_text()
