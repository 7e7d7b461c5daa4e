"""`coral logs TARGET` is one verb for both sides: the handle of a run on this machine prints that
run's logs as before, and any other name is a CoralSystem read from the cluster. The two sides
import nothing of each other; each registers its source in `coral.logs`."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from click.testing import CliRunner
from coral.local import state
from coral_core import logs_verb


@pytest.fixture
def a_local_run(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> state.RunRecord:
    monkeypatch.setenv("CORAL_STATE_DIR", str(tmp_path / "state"))
    run = state.RunRecord(
        handle="mission-a",
        group="mission",
        project=str(tmp_path),
        compose="compose.yaml",
        supervisor_pid=os.getpid(),
        started_at=0.0,
        components=[state.ComponentRecord(name="slam", role="skillset")],
    )
    run.save()
    (run.folder / "slam.log").write_text("Component slam ready\nmap updated\n")
    return run


def _logs(*args: str, kubeconfig: Path) -> tuple[int, str]:
    result = CliRunner(env={"KUBECONFIG": str(kubeconfig)}).invoke(logs_verb.logs_command, list(args))
    assert "Traceback" not in result.output, result.output
    return result.exit_code, result.output


def test_both_sides_are_installed_and_the_cluster_takes_what_no_run_claims() -> None:
    sources = logs_verb.installed_sources()
    assert [s.command.params[0].name for s in sources] == ["handle", "system"]


def test_a_run_handle_prints_that_runs_logs(a_local_run: state.RunRecord, tmp_path: Path) -> None:
    code, output = _logs("mission-a", kubeconfig=tmp_path / "none")
    assert (code, output) == (0, "slam | Component slam ready\nslam | map updated\n")


def test_any_other_name_is_a_coralsystem_in_the_cluster(a_local_run: state.RunRecord, tmp_path: Path) -> None:
    code, output = _logs("lidar-slam", "-n", "robots", "--robot", "r1", kubeconfig=tmp_path / "none")
    assert code == 1 and "no cluster to read from" in output, output


def test_options_of_the_fleet_form_never_reach_a_local_run(
    a_local_run: state.RunRecord, tmp_path: Path
) -> None:
    code, output = _logs("mission-a", "--since", "5m", kubeconfig=tmp_path / "none")
    assert code == 1 and "no cluster to read from" in output, output


def test_help_shows_both_forms(tmp_path: Path) -> None:
    code, output = _logs("--help", kubeconfig=tmp_path / "none")
    assert code == 0
    assert "[OPTIONS] HANDLE [SERVICES]..." in output and "[OPTIONS] SYSTEM" in output
