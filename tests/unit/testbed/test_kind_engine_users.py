"""The project's dockerd is not stopped by one run while another is making its cluster on it."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from coral_testbed.kind import engine

# Another run inside `kept_running`: it holds the users' lock shared, as that block does.
_ANOTHER_RUN = """
import fcntl, sys
users = open(sys.argv[1], "a")
fcntl.flock(users, fcntl.LOCK_SH)
print("inside", flush=True)
sys.stdin.read()
"""


def test_a_run_inside_kept_running_keeps_the_engine_and_its_end_lets_the_stop_ask_again(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("CORAL_CACHE_DIR", str(tmp_path))
    engine.engine_dir().mkdir(parents=True)
    asked: list[str] = []

    def in_use() -> bool:
        asked.append("asked")
        return True

    other = subprocess.Popen(
        [sys.executable, "-c", _ANOTHER_RUN, str(engine.engine_dir() / "users.lock")],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert other.stdout is not None and other.stdout.readline().strip() == "inside"
        assert engine.stop_unless(in_use) is False
        assert asked == [], "the stop looked for clusters while another run was making one"
    finally:
        assert other.stdin is not None
        other.stdin.close()
        other.wait(timeout=30)
    # That run is done: the stop decides by the clusters on the engine again.
    assert engine.stop_unless(in_use) is False
    assert asked == ["asked"]
