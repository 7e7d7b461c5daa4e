"""A skillset process signals readiness, then shuts down cleanly on SIGINT and SIGTERM."""

from __future__ import annotations

import signal
from pathlib import Path

import pytest
from coral.plugins import manifest as manifests
from fixtures.processes import Spawn

from .runtime_processes import finish, start_skillset

pytestmark = [pytest.mark.ros, pytest.mark.slow]


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_a_skillset_is_ready_after_export_and_clears_readiness_on_a_signal(
    tmp_path: Path, ros_env: dict[str, str], spawned: Spawn, signum: signal.Signals
) -> None:
    plugins = tmp_path / "plugins"
    log = tmp_path / "skillset.log"
    process = start_skillset(spawned, ros_env, plugins, log, name="lab_examples")
    folder = plugins / "lab_examples"
    manifest = manifests.read_manifest(folder)
    assert (manifest.component.name, manifest.component.node_name) == ("lab_examples", "lab_examples")
    assert "Component lab_examples ready" in log.read_text()
    process.send_signal(signum)
    assert finish(process, 30, log) == 0, log.read_text()
    assert not (folder / "ready").exists()
    assert "Component lab_examples stopping" in log.read_text()
    assert manifests.read_manifest(folder).behaviors, "the export stays for executors that loaded it"
