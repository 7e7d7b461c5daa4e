"""Readers of a Coral tree over Groot2's protocol: `coral tree watch --once --json` and the
third-party `btview` (acceptance 2 of issue 49), against a publisher whose tree is mid-run."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
from bt_stubs import R, S, make_tree
from click.testing import CliRunner
from coral_operator.tree_cli import tree_group
from groot2_stubs import publish

BODY = '<Sequence name="top"><Q name="a"/><SubTree ID="Sub" name="sub"/></Sequence>'
SUB = '<BehaviorTree ID="Sub"><Sequence><Script code="x := 1"/><Q name="b"/></Sequence></BehaviorTree>'


@pytest.fixture
def running():
    tree, _ = make_tree(BODY, {"a": [S], "b": [R]}, trees=SUB)
    with publish(tree) as publisher:
        tree.tick_exactly_once()
        yield tree, publisher


def test_tree_watch_once_json_prints_the_live_tree_with_its_statuses(running: tuple) -> None:
    tree, publisher = running
    result = CliRunner().invoke(
        tree_group, ["watch", "--port", str(publisher.port), "--once", "--json", "--blackboards"]
    )
    assert result.exit_code == 0, result.output
    snapshot = json.loads(result.output)
    assert snapshot["tree_uuid"] == publisher.tree_uuid.hex()
    assert snapshot["root_status"] == "RUNNING"
    top = snapshot["tree"]
    assert [(c["name"], c["status"]) for c in top["children"]] == [("a", "SUCCESS"), ("Sub", "RUNNING")]
    inner = top["children"][1]["children"][0]
    assert [(c["uid"], c["name"], c["status"]) for c in inner["children"]] == [
        (5, "Script", "SUCCESS"),
        (6, "b", "RUNNING"),
    ]
    assert snapshot["blackboards"]["sub"] == {"x": 1}


def test_tree_watch_once_draws_the_tree(running: tuple) -> None:
    _tree, publisher = running
    result = CliRunner().invoke(tree_group, ["watch", "--port", str(publisher.port), "--once"])
    assert result.exit_code == 0, result.output
    assert "b (Q)  RUNNING" in result.output and "Sub [sub]  RUNNING" in result.output


def test_tree_watch_says_when_nothing_answers() -> None:
    result = CliRunner().invoke(tree_group, ["watch", "--port", "9", "--once", "--timeout", "0.2"])
    assert result.exit_code != 0 and "cannot read a tree from 127.0.0.1:9" in result.output


def _btview(*args: str) -> str:
    done = subprocess.run(
        [sys.executable, "-m", "btview", *args], capture_output=True, text=True, timeout=60, check=True
    )
    return done.stdout


def test_btview_reads_a_snapshot_of_a_running_coral_tree(running: tuple) -> None:
    _tree, publisher = running
    port = str(publisher.port)
    lines = _btview("snapshot", "--port", port, "--uid", "--ascii", "--no-color", "--no-legend").splitlines()
    seen = {(line.split("#")[1].split()[0], line.split()[-1]) for line in lines if "#" in line}
    assert seen == {
        ("1", "RUNNING"),
        ("2", "SUCCESS"),
        ("3", "RUNNING"),
        ("4", "RUNNING"),
        ("5", "SUCCESS"),
        ("6", "RUNNING"),
    }
    assert json.loads(_btview("blackboard", "sub", "--json", "--port", port))["sub"] == {"x": 1}
    info = _btview("info", "--port", port)
    assert publisher.tree_uuid.hex() in info and "nodes          6" in info
