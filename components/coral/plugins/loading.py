"""Imports exported behavior modules in isolation and registers their classes with an engine registry.

Called by the executor after `discovery.discover`. Each component's `behaviors/` folder becomes a
private package named after the component and its content hash, so two skillsets that both ship
`behaviors.py` (or `utils.py`) never share or replace each other's modules, and a re-export with
new content loads under a new name.
"""

from __future__ import annotations

import importlib
import importlib.util
import sys
from typing import Any

from coral.plugins import discovery, hashing
from coral.plugins import manifest as manifests


class PluginLoadError(RuntimeError):
    """A verified plugin whose code failed to import; the message names component and module."""


def package_name(plugin: discovery.Plugin) -> str:
    return f"coral_plugin_{plugin.name}_{plugin.manifest.content_hash()}"


def _import_package(plugin: discovery.Plugin) -> str:
    name = package_name(plugin)
    if name in sys.modules:
        return name
    behaviors_dir = plugin.path / manifests.BEHAVIORS_DIR
    spec = importlib.util.spec_from_file_location(
        name, behaviors_dir / "__init__.py", submodule_search_locations=[str(behaviors_dir)]
    )
    if spec is None or spec.loader is None:
        raise PluginLoadError(f"plugin {plugin.name}: cannot import {behaviors_dir}")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return name


def add_interface_path(plugin: discovery.Plugin) -> None:
    """Puts `interfaces/` on the import path (after what is there: installed packages win)."""
    if plugin.manifest.interface_packages:
        folder = str(plugin.path / manifests.INTERFACES_DIR)
        if folder not in sys.path:
            sys.path.append(folder)


def load_classes(plugin: discovery.Plugin, node_ids: set[str]) -> dict[str, type]:
    """Imports the classes behind `node_ids` (all exported by `plugin`); raises `PluginLoadError`."""
    # The plugin folder belongs to its component (and may be a read-only volume): no bytecode there.
    previous = sys.dont_write_bytecode
    sys.dont_write_bytecode = True
    try:
        return _load_classes(plugin, node_ids)
    finally:
        sys.dont_write_bytecode = previous


def _load_classes(plugin: discovery.Plugin, node_ids: set[str]) -> dict[str, type]:
    # Checked again right before importing: the folder may have been replaced since discovery.
    changed = hashing.verify(plugin.path, plugin.manifest.files)
    if changed is not None:
        raise PluginLoadError(f"plugin {plugin.name}: {changed}")
    add_interface_path(plugin)
    try:
        package = _import_package(plugin)
    except Exception as err:  # noqa: BLE001 - any error in foreign code is a load failure
        raise PluginLoadError(f"plugin {plugin.name}: behaviors/__init__.py failed to import: {err}") from err
    classes: dict[str, type] = {}
    for entry in plugin.manifest.behaviors:
        if entry.id not in node_ids:
            continue
        try:
            module: Any = importlib.import_module(f"{package}.{entry.module}")
        except Exception as err:  # noqa: BLE001
            raise PluginLoadError(
                f"plugin {plugin.name}: module behaviors/{entry.module}.py failed to import: "
                f"{type(err).__name__}: {err}"
            ) from err
        cls = getattr(module, entry.class_name, None)
        if not isinstance(cls, type):
            raise PluginLoadError(
                f"plugin {plugin.name}: module {entry.module} has no class {entry.class_name}"
            )
        cls.CORAL_COMPONENT = plugin.manifest.component  # type: ignore[attr-defined]
        classes[entry.id] = cls
    return classes
