"""The rich UI as a person sees it on a terminal (read through a terminal emulator), and plain in pipes."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

from fixtures.terminal import run_on_terminal

# A tiny `coral run` session without ROS: component lines and executor records through the Console.
LIVE_SESSION = """
import sys
from coral.local.console import Console, TreeView

console = Console()
for name in ("slam", "executor"):
    console.register(name)
console.log("slam", "Component slam ready")
view = TreeView()
for record in [
    {"event": "transition", "path": "Main::1", "node_id": "Sequence", "status": "RUNNING"},
    {"event": "transition", "path": "Main::1/Map::2", "node_id": "ProcessScan", "status": "RUNNING"},
    {"event": "status", "root_status": "RUNNING", "tick_count": 7, "active_path": "Main::1/Map::2"},
]:
    view.apply(record)
    console.show(view)
console.log("executor", "tick 7")
for record in [
    {"event": "transition", "path": "Main::1/Map::2", "node_id": "ProcessScan", "status": "FAILURE"},
    {"event": "finished", "root_status": "FAILURE", "exit_code": 1, "tick_count": 9},
]:
    view.apply(record)
    console.show(view)
console.close_footer()
console.note("Run finished")
"""


def _env(tmp_path: Path) -> dict[str, str]:
    return {**os.environ, "CORAL_STATE_DIR": str(tmp_path / "state")}


def test_the_live_tree_footer_stays_below_the_logs_and_shows_each_node_status(tmp_path: Path) -> None:
    screen = run_on_terminal([sys.executable, "-c", LIVE_SESSION], _env(tmp_path))
    assert screen.returncode == 0, screen.text
    lines = [line for line in screen.lines if line]
    assert lines[0] == "slam     | Component slam ready"
    assert lines[1] == "executor | tick 7"
    # The footer was redrawn in place: one copy of it, with the last statuses, then the closing note.
    assert sum(line.startswith("tree ") for line in lines) == 1
    footer = lines[lines.index("tree FAILURE  ticks 9") :]
    assert footer[1].split() == ["Sequence", "RUNNING"]
    assert footer[2].split() == ["▶", "ProcessScan", "FAILURE"]
    assert footer[2].index("ProcessScan") > footer[1].index("Sequence")  # indented by depth
    assert footer[3] == "coral    | Run finished"
    assert b"\x1b[31m" in screen.raw or b"\x1b[31;" in screen.raw  # FAILURE in red


def test_piped_the_same_session_prints_plain_progress_lines_without_escape_codes(tmp_path: Path) -> None:
    piped = subprocess.run(
        [sys.executable, "-c", LIVE_SESSION],
        env={**_env(tmp_path), "TERM": "xterm-256color"},
        capture_output=True,
        timeout=60,
        check=True,
    )
    assert b"\x1b" not in piped.stdout
    assert piped.stdout.decode().splitlines() == [
        "slam     | Component slam ready",
        "coral    | tree IDLE ticks=0",
        "coral    | tree RUNNING ticks=7 active=Main::1/Map::2",
        "executor | tick 7",
        "coral    | tree FAILURE ticks=9 active=Main::1/Map::2",
        "coral    | Run finished",
    ]


def _record_run(tmp_path: Path) -> None:
    """A run record as `coral run` writes it, whose supervisor (this test) is alive."""
    folder = tmp_path / "state" / "runs" / "lidar-slam-abc123"
    folder.mkdir(parents=True)
    record = {
        "handle": "lidar-slam-abc123",
        "group": "lidar-slam",
        "project": "lidar-slam",
        "compose": "compose.yaml",
        "supervisor_pid": os.getpid(),
        "started_at": time.time() - 42,
        "state": "running",
        "components": [
            {"name": "bag_player", "role": "driver", "state": "exited", "exit_code": 0},
            {"name": "slam", "role": "skillset", "state": "ready"},
            {"name": "executor", "role": "executor", "state": "failed", "exit_code": 3},
        ],
    }
    (folder / "run.json").write_text(json.dumps(record))


def test_coral_ps_draws_a_table_on_a_terminal_and_plain_text_in_a_pipe(tmp_path: Path) -> None:
    _record_run(tmp_path)
    argv = [sys.executable, "-m", "coral", "ps"]
    screen = run_on_terminal(argv, _env(tmp_path))
    assert screen.returncode == 0, screen.text
    header, row = [line for line in screen.lines if line][:2]
    assert header.split() == ["HANDLE", "GROUP", "STATE", "AGE", "COMPONENTS"]
    assert row.split()[:3] == ["lidar-slam-abc123", "lidar-slam", "running"]
    assert row.split()[3] in ("42s", "43s", "44s")
    assert "bag_player(d):exited/0, slam(s):ready, executor(e):failed/3" in row
    assert row.index("running") == header.index("STATE")  # columns line up
    assert b"\x1b[" in screen.raw

    piped = subprocess.run(argv, env=_env(tmp_path), capture_output=True, timeout=60, check=True)
    assert b"\x1b" not in piped.stdout
    assert piped.stdout.decode().splitlines()[1].split()[:3] == ["lidar-slam-abc123", "lidar-slam", "running"]
