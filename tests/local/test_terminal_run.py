"""`coral run` as a person sees it: on a terminal (read through a terminal emulator) the live tree
view stays below the logs and ends with every node's last result; piped, plain lines only."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest
from fixtures.terminal import run_on_terminal
from run_helpers import coral

pytestmark = [pytest.mark.ros]

TREE = """<root BTCPP_format="4" main_tree_to_execute="Main">
  <BehaviorTree ID="Main">
    <Sequence>
      <Sleep msec="300"/>
      <Fallback>
        <AlwaysFailure/>
        <AlwaysSuccess/>
      </Fallback>
    </Sequence>
  </BehaviorTree>
</root>
"""


@pytest.fixture
def project(tmp_path: Path) -> Path:
    """An executor alone, on built-in nodes only: the quickest real `coral run`."""
    folder = tmp_path / "tiny"
    folder.mkdir()
    (folder / "compose.yaml").write_text("services:\n  executor:\n    profiles: [executors]\n")
    (folder / "tree.xml").write_text(TREE)
    return folder


def test_on_a_terminal_the_tree_view_ends_below_the_logs_with_each_node_result(
    project: Path, ros_env: dict[str, str], tmp_path: Path
) -> None:
    env = {**ros_env, "CORAL_STATE_DIR": str(tmp_path / "state")}
    argv = coral("run", str(project), "--output", str(tmp_path / "out"))
    screen = run_on_terminal(argv, env, columns=140, timeout=120)
    assert screen.returncode == 0, screen.text
    lines = [line for line in screen.lines if line]
    heads = [i for i, line in enumerate(lines) if line.startswith("tree ")]
    assert len(heads) == 1, screen.text  # redrawn in place, never repeated
    footer = lines[heads[0] : heads[0] + 6]
    assert footer[0].split()[:2] == ["tree", "SUCCESS"]
    assert [line.split() for line in footer[1:]] == [
        ["Sequence", "(success)"],
        ["Sleep", "(success)"],
        ["Fallback", "(success)"],
        ["AlwaysFailure", "(failure)"],
        ["AlwaysSuccess", "(success)"],
    ]
    assert [len(line) - len(line.lstrip()) for line in footer[1:]] == [2, 4, 4, 6, 6]  # by depth
    assert lines.index("coral    | Executor executor finished: tree SUCCESS, exit code 0") < heads[0]
    assert lines[-1].startswith("coral    | Run tiny-") and lines[-1].endswith("finished with exit code 0")
    assert b"\x1b[" in screen.raw


def test_piped_the_run_prints_plain_progress_lines(
    project: Path, ros_env: dict[str, str], tmp_path: Path
) -> None:
    env = {**ros_env, "CORAL_STATE_DIR": str(tmp_path / "state"), "TERM": "xterm-256color"}
    argv = coral("run", str(project), "--output", str(tmp_path / "out"))
    piped = subprocess.run(argv, env=env, capture_output=True, timeout=120)
    assert piped.returncode == 0, piped.stdout.decode()
    assert b"\x1b" not in piped.stdout
    text = piped.stdout.decode()
    assert "coral    | tree SUCCESS ticks=" in text and "(success)" not in text
