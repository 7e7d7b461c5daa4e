"""`coral executor` refuses options ROS or the tick loop cannot take before it starts anything: a
node name or status topic ROS would refuse exits 2 (bad input) with rclpy's own explanation, not a
traceback and exit 4; a tick rate must be above 0 and at most the limit a CoralSystem has."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner
from coral_core.command import main
from coral_core.limits import MAX_TICK_RATE_HZ

TREE = '<root BTCPP_format="4"><BehaviorTree ID="Main"><AlwaysSuccess/></BehaviorTree></root>'


@pytest.fixture
def project(tmp_path: Path) -> Path:
    (tmp_path / "tree.xml").write_text(TREE)
    (tmp_path / "plugins").mkdir()
    return tmp_path


def _executor(project: Path, *options: str) -> tuple[int, str, list[dict[str, object]]]:
    status = project / "status.jsonl"
    arguments = ["executor", "--tree", str(project / "tree.xml"), "--plugins", str(project / "plugins")]
    result = CliRunner().invoke(main, [*arguments, "--status-jsonl", str(status), *options])
    records = [json.loads(line) for line in status.read_text().splitlines()] if status.exists() else []
    return result.exit_code, result.output, records


@pytest.mark.parametrize(
    ("options", "explanation"),
    [
        (["--name", "coral-executor"], "Invalid node name: node name must not contain characters other than"),
        (["--status-topic", "coral//status"], "Invalid topic name: topic name must not contain repeated '/'"),
    ],
)
def test_a_name_ros_refuses_is_bad_input_named_by_rclpy(
    project: Path, options: list[str], explanation: str
) -> None:
    code, output, records = _executor(project, *options)
    assert code == 2, output
    assert "Traceback" not in output
    (error,) = [r for r in records if r.get("event") == "error"]
    assert str(error["message"]).startswith(explanation)
    assert records[-1]["event"] == "finished" and records[-1]["exit_code"] == 2


@pytest.mark.parametrize("rate", ["0", "-1", "inf", "nan", str(MAX_TICK_RATE_HZ * 2)])
def test_a_tick_rate_outside_its_range_is_refused_by_the_command_line(project: Path, rate: str) -> None:
    code, output, records = _executor(project, "--rate", rate)
    assert code == 2 and "Invalid value for '--rate'" in output
    assert records == []  # refused before the executor started
