"""The mission follower of `coral demo`: a live table on a terminal, plain lines in a pipe."""

from __future__ import annotations

import io
import os
import subprocess
import sys
from typing import Any

from coral_core import terminal
from coral_testbed.missions import following
from fixtures.terminal import run_on_terminal


def _instance(robot: str, root: str, ticks: int, active: str = "", ready: bool = True) -> dict[str, Any]:
    conditions = [{"type": "Ready", "status": "True" if ready else "False", "reason": "PodsNotReady"}]
    return {
        "metadata": {"name": f"slam-{robot}"},
        "spec": {"robot": robot},
        "status": {
            "tree": {"rootStatus": root, "tickCount": ticks, "activePath": active},
            "conditions": conditions,
        },
    }


def test_the_table_has_a_row_a_robot_with_its_tree_and_what_is_wrong() -> None:
    stream = io.StringIO()
    terminal.console(stream).print(
        following.table(
            [
                _instance("robot-2", "RUNNING", 12, "Main/ProcessScan", ready=False),
                _instance("robot-1", "SUCCESS", 340),
            ]
        )
    )
    header, first, second = stream.getvalue().splitlines()
    assert header.split() == ["ROBOT", "TREE", "TICKS", "ACTIVE", "NODE", "PROBLEMS"]
    assert first.split() == ["robot-1", "SUCCESS", "340"]
    assert second.split() == ["robot-2", "RUNNING", "12", "Main/ProcessScan", "[PodsNotReady]"]
    assert "\x1b" not in stream.getvalue()


def test_follow_shows_every_poll_and_echoes_a_robot_only_when_its_tree_moved() -> None:
    polls = iter(
        [
            [_instance("robot-1", "RUNNING", 1, "Main/A")],
            [_instance("robot-1", "RUNNING", 2, "Main/A")],
            [_instance("robot-1", "SUCCESS", 3, "Main/B")],
        ]
    )
    shown: list[int] = []
    echoed: list[str] = []
    final = following.follow(
        lambda: next(polls),
        lambda items: following.finished(items, ["robot-1"]),
        timeout=10,
        echo=echoed.append,
        show=lambda items: shown.append(following.tree(items[0])["tickCount"]),
        interval=0.0,
    )
    assert shown == [1, 2, 3] and following.tree(final[0])["rootStatus"] == "SUCCESS"
    assert [line.split()[:2] for line in echoed] == [["robot-1", "RUNNING"], ["robot-1", "SUCCESS"]]


LIVE_FOLLOWER = """
from coral_core import terminal
from coral_testbed.missions import following
from rich.live import Live

def instance(root, ticks):
    return {"metadata": {"name": "i"}, "spec": {"robot": "robot-1"},
            "status": {"tree": {"rootStatus": root, "tickCount": ticks, "activePath": "Main/Scan"}}}

polls = iter([[instance("RUNNING", n)] for n in range(1, 6)] + [[instance("SUCCESS", 9)]])
out = terminal.console()
with Live(following.table([]), console=out, auto_refresh=False) as live:
    following.follow(lambda: next(polls), lambda items: following.finished(items, ["robot-1"]),
                     timeout=10, interval=0.0,
                     show=lambda items: live.update(following.table(items), refresh=True))
"""


def test_on_a_terminal_the_table_is_redrawn_in_place() -> None:
    screen = run_on_terminal([sys.executable, "-c", LIVE_FOLLOWER], dict(os.environ))
    assert screen.returncode == 0, screen.text
    lines = [line for line in screen.lines if line]
    assert len(lines) == 2, lines  # one header, one robot: every poll drew over the last
    assert lines[1].split() == ["robot-1", "SUCCESS", "9", "Main/Scan"]
    assert b"\x1b[32mSUCCESS" in screen.raw

    piped = subprocess.run([sys.executable, "-c", LIVE_FOLLOWER], capture_output=True, timeout=60)
    assert piped.returncode == 0 and b"\x1b" not in piped.stdout


def test_the_tree_statuses_are_the_root_the_running_chain_and_the_last_failure() -> None:
    running = _instance("robot-1", "RUNNING", 5, "Sequence::1/StartSLAM::2/Sequence::3/Wait::5")
    running["status"]["tree"]["lastFailure"] = {"path": "Sequence::1/Fallback::10/IsStopRequested::11"}
    assert following.tree_statuses(running) == {
        1: "RUNNING",
        2: "RUNNING",
        3: "RUNNING",
        5: "RUNNING",
        11: "FAILURE",
    }
    done = _instance("robot-1", "SUCCESS", 9, "")
    assert following.tree_statuses(done) == {1: "SUCCESS"}
