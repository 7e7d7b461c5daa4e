"""An executor refuses incompatible or corrupt plugins with a reason and resolves clashes the same way
every time (DESIGN section 4, issue 4 acceptance 3, at the file level)."""

from __future__ import annotations

import json
from pathlib import Path

import coral
from coral.plugins import compat, discovery

from .plugin_builders import greeter_plugin

DISTRO = compat.current_ros_distro()


def _discover(root: Path, builtin_ids: tuple[str, ...] = ()) -> discovery.DiscoveryReport:
    return discovery.discover(
        root, ros_distro=DISTRO, coral_version=coral.__version__, builtin_ids=builtin_ids
    )


def _rewrite_manifest(folder: Path, **changes: object) -> None:
    raw = json.loads((folder / "manifest.json").read_text())
    raw.update(changes)
    (folder / "manifest.json").write_text(json.dumps(raw))


def test_a_plugin_for_another_coral_major_version_is_refused_with_both_versions(tmp_path: Path) -> None:
    _rewrite_manifest(greeter_plugin(tmp_path, "old", "Hello", "hi"), coral_version="7.0.0")
    report = _discover(tmp_path)
    assert report.plugins == []
    [refusal] = report.refused
    assert refusal.folder == "old"
    assert "Coral 7.0.0" in refusal.reason and f"Coral {coral.__version__}" in refusal.reason


def test_a_plugin_for_another_ros_distro_is_refused(tmp_path: Path) -> None:
    _rewrite_manifest(greeter_plugin(tmp_path, "humble_one", "Hello", "hi"), ros_distro="humble")
    [refusal] = _discover(tmp_path).refused
    assert refusal.reason == f"exported for ROS humble, this executor runs ROS {DISTRO}"


def test_an_unknown_schema_version_is_refused(tmp_path: Path) -> None:
    _rewrite_manifest(greeter_plugin(tmp_path, "future", "Hello", "hi"), schema_version=99)
    [refusal] = _discover(tmp_path).refused
    assert "schema version 99 is not supported" in refusal.reason


def test_a_modified_behavior_file_fails_its_hash_check(tmp_path: Path) -> None:
    folder = greeter_plugin(tmp_path, "tampered", "Hello", "hi")
    module = folder / "behaviors" / "behaviors.py"
    module.write_text(module.read_text().replace('"hi"', '"pwned"'))
    [refusal] = _discover(tmp_path).refused
    assert (
        refusal.reason
        == "file behaviors/behaviors.py does not match its sha256 in the manifest (corrupt or modified)"
    )


def test_a_file_not_listed_in_the_manifest_is_refused(tmp_path: Path) -> None:
    folder = greeter_plugin(tmp_path, "extra", "Hello", "hi")
    (folder / "behaviors" / "sneaky.py").write_text("print('hello')\n")
    [refusal] = _discover(tmp_path).refused
    assert refusal.reason == "file behaviors/sneaky.py is not listed in the manifest"


def test_a_folder_without_a_manifest_is_refused_and_hidden_staging_folders_are_ignored(
    tmp_path: Path,
) -> None:
    (tmp_path / "stray").mkdir()
    (tmp_path / ".alpha.tmp-123").mkdir()
    report = _discover(tmp_path)
    assert [r.folder for r in report.refused] == ["stray"]
    assert "cannot read" in report.refused[0].reason


def test_a_clash_keeps_the_first_component_by_name_and_reports_the_other(tmp_path: Path) -> None:
    greeter_plugin(tmp_path, "zeta", "Hello", "from zeta")
    greeter_plugin(tmp_path, "alpha", "Hello", "from alpha")
    report = _discover(tmp_path)
    assert [p.name for p in report.plugins] == ["alpha", "zeta"]
    assert report.providers["Hello"][0].name == "alpha"
    [conflict] = report.conflicts
    assert conflict.describe() == (
        "node ID Hello is exported by both alpha and zeta; using alpha (first by component name)"
    )


def test_clash_reports_are_identical_on_every_scan(tmp_path: Path) -> None:
    for name in ("m", "b", "x", "a"):
        greeter_plugin(tmp_path, name, "Hello", name)
    first = [c.describe() for c in _discover(tmp_path).conflicts]
    assert first == [c.describe() for c in _discover(tmp_path).conflicts]
    assert [(c.kept, c.dropped) for c in _discover(tmp_path).conflicts] == [
        ("a", "b"),
        ("a", "m"),
        ("a", "x"),
    ]


def test_a_plugin_cannot_replace_a_built_in_node(tmp_path: Path) -> None:
    greeter_plugin(tmp_path, "sneaky", "Sequence", "no")
    report = _discover(tmp_path, builtin_ids=("Sequence",))
    assert "Sequence" not in report.providers
    assert report.conflicts[0].describe().endswith("using builtin (built in)")
