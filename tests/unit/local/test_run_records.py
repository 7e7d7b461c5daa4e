"""Run records for `coral ps/stop/logs`: selection by handle or group, dead supervisors, orphans."""

from __future__ import annotations

import os
import time
from pathlib import Path

import pytest
from coral.local import state


@pytest.fixture(autouse=True)
def private_state(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv("CORAL_STATE_DIR", str(tmp_path))
    return tmp_path


def _record(handle: str, group: str, pid: int, **fields: object) -> state.RunRecord:
    record = state.RunRecord(
        handle=handle,
        group=group,
        project="p",
        compose="c.yaml",
        supervisor_pid=pid,
        started_at=time.time(),
        **fields,
    )  # type: ignore[arg-type]
    record.save()
    return record


def test_runs_are_selected_by_handle_group_or_all() -> None:
    _record("a", "lab", os.getpid())
    _record("b", "lab", os.getpid())
    _record("c", "field", os.getpid())
    runs = state.load_runs()
    assert {r.handle for r in state.select_runs(runs, handle="a", group=None, everything=False)} == {"a"}
    assert {r.handle for r in state.select_runs(runs, handle=None, group="lab", everything=False)} == {
        "a",
        "b",
    }
    assert len(state.select_runs(runs, handle=None, group=None, everything=True)) == 3


def test_a_run_whose_supervisor_is_gone_reads_as_finished(tmp_path: Path) -> None:
    import subprocess
    import sys

    gone = subprocess.run(
        [sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True
    )
    _record("dead", "g", int(gone.stdout))
    (run,) = state.load_runs()
    assert run.state == "finished" and run.message == "supervisor is gone"


def test_only_live_processes_running_the_recorded_command_count_as_orphans() -> None:
    import subprocess
    import sys

    child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"], start_new_session=True)
    try:
        dead = subprocess.run(
            [sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True
        )
        components = [
            state.ComponentRecord(name="real", role="skillset", pid=child.pid, command=child.args),  # type: ignore[arg-type]
            state.ComponentRecord(
                name="reused", role="skillset", pid=os.getpid(), command=["something", "else"]
            ),
        ]
        run = _record("orphans", "g", int(dead.stdout), components=components)
        assert [c.name for c in state.orphaned_components(run)] == ["real"]
        state.kill_group(child.pid)
        assert child.wait(timeout=10) != 0
    finally:
        if child.poll() is None:
            child.kill()
