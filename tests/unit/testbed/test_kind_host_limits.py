"""The host's inotify limits: raised where too low for kind's nodes, never lowered, and a refusal
said rather than raised."""

from __future__ import annotations

from pathlib import Path

import pytest
from coral_testbed.kind import hostlimits


def _limits(folder: Path, **values: int) -> Path:
    for name, value in values.items():
        (folder / name).write_text(f"{value}\n")
    return folder


def _read(folder: Path) -> dict[str, int]:
    return {path.name: int(path.read_text()) for path in folder.iterdir()}


def test_a_default_host_gets_kinds_values_and_each_change_is_told(tmp_path: Path) -> None:
    folder = _limits(tmp_path, max_user_instances=128, max_user_watches=8192)
    lines = hostlimits.ensure(folder)
    assert _read(folder) == hostlimits.WANTED
    assert lines == [
        "fs.inotify.max_user_instances raised from 128 to 512 (kind's nodes need it)",
        "fs.inotify.max_user_watches raised from 8192 to 524288 (kind's nodes need it)",
    ]


def test_higher_limits_are_left_as_they_are(tmp_path: Path) -> None:
    folder = _limits(tmp_path, max_user_instances=8192, max_user_watches=524288)
    assert hostlimits.ensure(folder) == []
    assert _read(folder) == {"max_user_instances": 8192, "max_user_watches": 524288}


def test_only_the_low_one_is_raised(tmp_path: Path) -> None:
    folder = _limits(tmp_path, max_user_instances=128, max_user_watches=1048576)
    (line,) = hostlimits.ensure(folder)
    assert "max_user_instances" in line
    assert _read(folder) == {"max_user_instances": 512, "max_user_watches": 1048576}


def test_a_limit_that_cannot_be_written_is_named_with_what_to_do(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    folder = _limits(tmp_path, max_user_instances=128, max_user_watches=524288)

    def refuse(self: Path, text: str) -> int:
        raise PermissionError(13, "Permission denied")

    # A read-only /proc/sys cannot be made from a temporary folder as root: the refusal is mocked.
    monkeypatch.setattr(Path, "write_text", refuse)
    (line,) = hostlimits.ensure(folder)
    assert line.startswith("fs.inotify.max_user_instances stays 128 (Permission denied)")
    assert "raise it to 512" in line


def test_a_setting_the_host_lacks_is_left_alone(tmp_path: Path) -> None:
    folder = _limits(tmp_path, max_user_instances=128)
    (line,) = hostlimits.ensure(folder)
    assert "max_user_instances raised" in line
    assert _read(folder) == {"max_user_instances": 512}
