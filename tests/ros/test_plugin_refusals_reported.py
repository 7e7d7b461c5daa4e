"""The executor reports refused and clashing plugins with reasons, identically on every run (acceptance 3)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from coral.plugins import exporting
from coral.plugins import manifest as manifests
from coral_skillsets.examples import behaviors
from fixtures.processes import Spawn

from .runtime_processes import finish, records_of, start_executor, start_skillset, write_tree

pytestmark = [pytest.mark.ros, pytest.mark.slow]


def _export(plugins: Path, name: str) -> Path:
    ref = manifests.ComponentRef(name=name, kind="skillset", node_name=name)
    return exporting.export_plugin(plugins, ref, [behaviors.Greet])


def test_incompatible_corrupt_and_clashing_plugins_are_reported_the_same_way_twice(
    tmp_path: Path, ros_env: dict[str, str], spawned: Spawn
) -> None:
    plugins = tmp_path / "plugins"
    start_skillset(spawned, ros_env, plugins, tmp_path / "a.log")
    start_skillset(spawned, ros_env, plugins, tmp_path / "b.log", name="examples_copy")
    legacy = _export(plugins, "legacy")
    raw = json.loads((legacy / "manifest.json").read_text())
    raw["coral_version"] = "9.1.0"
    (legacy / "manifest.json").write_text(json.dumps(raw))
    corrupt = _export(plugins, "corrupt")
    (corrupt / "behaviors" / "behaviors.py").write_text("raise SystemExit('never imported')\n")
    tree = write_tree(tmp_path / "tree.xml", '    <Greet who="fleet" greeting="{g}"/>')

    reports = []
    for run in range(2):
        status = tmp_path / f"status{run}.jsonl"
        log = tmp_path / f"executor{run}.log"
        assert finish(start_executor(spawned, ros_env, tree, plugins, status, log), 60, log) == 0, (
            log.read_text()
        )
        record = records_of(status, "plugins")[-1]
        reports.append((record["refused"], record["conflicts"], record["loaded"]))
    assert reports[0] == reports[1], "the same plugin location is reported identically on every run"
    refused, conflicts, loaded = reports[0]
    reasons = {item["plugin"]: item["reason"] for item in refused}
    assert set(reasons) == {"legacy", "corrupt"}
    assert "exported for Coral 9.1.0" in reasons["legacy"]
    assert "behaviors/behaviors.py does not match its sha256" in reasons["corrupt"]
    assert [c["message"] for c in conflicts] == [
        f"node ID {node_id} is exported by both examples and examples_copy; "
        "using examples (first by component name)"
        for node_id in ("Greet", "Count", "IsAtLeast", "WaitForCount")
    ]
    assert loaded == [{"component": "examples", "behaviors": ["Greet"]}]
