"""A component's export writes a complete, verifiable plugin folder atomically."""

from __future__ import annotations

from pathlib import Path

import coral
import pytest
from coral.plugins import compat, discovery, exporting
from coral.plugins import manifest as manifests
from coral_core.bt import PortDirection, PortSpec, Status
from coral_core.bt.leaves import SyncAction
from coral_skillsets.examples import behaviors

COMPONENT = manifests.ComponentRef(name="examples", kind="skillset", node_name="examples", namespace="/")
EXAMPLES = [behaviors.Greet, behaviors.Count, behaviors.IsAtLeast]


def test_the_export_lists_kinds_ports_and_hashes_and_passes_discovery(tmp_path: Path) -> None:
    folder = exporting.export_plugin(tmp_path, COMPONENT, EXAMPLES)
    manifest = manifests.read_manifest(folder)
    assert [(b.id, b.kind, b.module, b.class_name) for b in manifest.behaviors] == [
        ("Greet", "action", "behaviors", "Greet"),
        ("Count", "action", "behaviors", "Count"),
        ("IsAtLeast", "condition", "behaviors", "IsAtLeast"),
    ]
    greet_ports = {(p.name, p.direction, p.type, p.default) for p in manifest.behaviors[0].ports}
    assert greet_ports == {("who", "input", "string", "world"), ("greeting", "output", "string", None)}
    assert set(manifest.files) == {"behaviors/__init__.py", "behaviors/behaviors.py"}
    assert manifest.coral_version == coral.__version__
    report = discovery.discover(
        tmp_path, ros_distro=compat.current_ros_distro(), coral_version=coral.__version__
    )
    assert report.refused == [] and sorted(report.providers) == ["Count", "Greet", "IsAtLeast"]


def test_a_re_export_replaces_the_folder_and_leaves_no_staging_behind(tmp_path: Path) -> None:
    first = exporting.export_plugin(tmp_path, COMPONENT, EXAMPLES[:1])
    exporting.mark_ready(first, "examples\n")
    second = exporting.export_plugin(tmp_path, COMPONENT, EXAMPLES)
    assert first == second
    assert sorted(p.name for p in tmp_path.iterdir()) == ["examples"]
    assert len(manifests.read_manifest(second).behaviors) == 3
    assert not (second / "ready").exists(), "a fresh export is not ready until the component says so"


def test_ready_marker_is_written_and_cleared(tmp_path: Path) -> None:
    folder = exporting.export_plugin(tmp_path, COMPONENT, EXAMPLES)
    exporting.mark_ready(folder, "examples\n")
    assert (folder / "ready").read_text() == "examples\n"
    assert discovery.inspect_plugin(
        folder, ros_distro=compat.current_ros_distro(), coral_version=coral.__version__
    )
    exporting.clear_ready(folder)
    assert not (folder / "ready").exists()


class NameClash(SyncAction):
    PORTS = [PortSpec("name", PortDirection.INPUT, "string")]

    def tick(self) -> Status:
        return Status.SUCCESS


def test_a_port_named_like_a_bt_cpp_attribute_is_refused_at_export(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="port name 'name' is reserved"):
        exporting.export_plugin(tmp_path, COMPONENT, [NameClash])
    assert list(tmp_path.iterdir()) == [], "a failed export leaves nothing behind"


def test_interface_packages_are_exported_and_hashed(tmp_path: Path) -> None:
    package = tmp_path / "src" / "my_msgs"
    package.mkdir(parents=True)
    (package / "__init__.py").write_text("VALUE = 42\n")
    folder = exporting.export_plugin(
        tmp_path / "plugins", COMPONENT, EXAMPLES, interface_packages=[str(package)]
    )
    manifest = manifests.read_manifest(folder)
    assert manifest.interface_packages == ["my_msgs"]
    assert "interfaces/my_msgs/__init__.py" in manifest.files
