"""Behaviors load without prior knowledge, each component's modules in a package of its own."""

from __future__ import annotations

from pathlib import Path

import coral
import pytest
from coral.plugins import compat, discovery, loading
from coral_core.bt import NodeRegistry, build_tree, load_tree_text

from .plugin_builders import greeter_plugin, write_plugin

TREE = """
<root BTCPP_format="4">
  <BehaviorTree ID="Main">
    <Sequence>
      <HelloA greeting="{a}"/>
      <HelloB greeting="{b}"/>
    </Sequence>
  </BehaviorTree>
</root>
"""


def test_two_components_with_the_same_module_name_load_side_by_side(tmp_path: Path) -> None:
    greeter_plugin(tmp_path, "first", "HelloA", "from first", module="behaviors")
    greeter_plugin(tmp_path, "second", "HelloB", "from second", module="behaviors")
    report = discovery.discover(
        tmp_path, ros_distro=compat.current_ros_distro(), coral_version=coral.__version__
    )
    registry = NodeRegistry.with_builtins()
    module_names = set()
    for plugin in report.plugins:
        ids = {entry.id for entry in plugin.manifest.behaviors}
        for node_id, cls in loading.load_classes(plugin, ids).items():
            registry.register(node_id, cls, source=plugin.name)
            module_names.add(cls.__module__)
    # Both files are behaviors/behaviors.py, yet each has its own module object.
    assert len(module_names) == 2
    assert all(name.startswith("coral_plugin_") and name.endswith(".behaviors") for name in module_names)
    tree = build_tree(load_tree_text(TREE), registry)
    assert tree.tick_once().name == "SUCCESS"
    assert (tree.root_blackboard.get("a"), tree.root_blackboard.get("b")) == ("from first", "from second")


def test_a_module_that_fails_to_import_is_reported_with_component_and_module(tmp_path: Path) -> None:
    folder = greeter_plugin(tmp_path, "broken", "Broken", "x")
    # Re-export with a syntax error but consistent hashes, as a buggy skillset would.
    folder.rename(tmp_path / "old_broken")
    write_plugin(
        tmp_path,
        "broken",
        {"behaviors": "def oops(:\n"},
        [{"id": "Broken", "kind": "action", "module": "behaviors", "class": "Broken"}],
    )
    [plugin] = [
        p
        for p in discovery.discover(
            tmp_path, ros_distro=compat.current_ros_distro(), coral_version=coral.__version__
        ).plugins
        if p.name == "broken"
    ]
    try:
        loading.load_classes(plugin, {"Broken"})
    except loading.PluginLoadError as err:
        assert "plugin broken: module behaviors/behaviors.py failed to import: SyntaxError" in str(err)
    else:
        raise AssertionError("a module with a syntax error loaded")


INTERFACE_USER = """
from coral_core.bt import PortDirection, PortSpec, Status
from coral_core.bt.leaves import SyncAction
from coral_test_exported_msgs import GREETING


class UsesInterface(SyncAction):
    PORTS = [PortSpec("greeting", PortDirection.OUTPUT, "string")]

    def tick(self) -> Status:
        self.set_output("greeting", GREETING)
        return Status.SUCCESS
"""


def test_exported_interface_packages_are_importable_by_the_behaviors(tmp_path: Path) -> None:
    write_plugin(
        tmp_path,
        "with_msgs",
        {"behaviors": INTERFACE_USER},
        [{"id": "UsesInterface", "kind": "action", "module": "behaviors", "class": "UsesInterface"}],
        interfaces={"coral_test_exported_msgs": "GREETING = 'from an exported package'\n"},
    )
    [plugin] = discovery.discover(
        tmp_path, ros_distro=compat.current_ros_distro(), coral_version=coral.__version__
    ).plugins
    assert plugin.manifest.interface_packages == ["coral_test_exported_msgs"]
    registry = NodeRegistry.with_builtins()
    for node_id, cls in loading.load_classes(plugin, {"UsesInterface"}).items():
        registry.register(node_id, cls, source=plugin.name)
    document = load_tree_text(
        '<root BTCPP_format="4"><BehaviorTree ID="M"><UsesInterface greeting="{g}"/></BehaviorTree></root>'
    )
    tree = build_tree(document, registry)
    assert tree.tick_once().name == "SUCCESS"
    assert tree.root_blackboard.get("g") == "from an exported package"


def test_loading_writes_nothing_into_the_plugin_folder(tmp_path: Path) -> None:
    folder = greeter_plugin(tmp_path, "tidy", "HelloTidy", "hi")
    before = sorted(p.relative_to(folder) for p in folder.rglob("*"))
    [plugin] = discovery.discover(
        tmp_path, ros_distro=compat.current_ros_distro(), coral_version=coral.__version__
    ).plugins
    loading.load_classes(plugin, {"HelloTidy"})
    assert sorted(p.relative_to(folder) for p in folder.rglob("*")) == before


def test_code_changed_after_discovery_is_not_imported(tmp_path: Path) -> None:
    folder = greeter_plugin(tmp_path, "swapped", "HelloSwapped", "hi")
    [plugin] = discovery.discover(
        tmp_path, ros_distro=compat.current_ros_distro(), coral_version=coral.__version__
    ).plugins
    (folder / "behaviors" / "behaviors.py").write_text("raise RuntimeError('must never run')\n")
    with pytest.raises(loading.PluginLoadError, match="does not match its sha256"):
        loading.load_classes(plugin, {"HelloSwapped"})
