"""The executor's wait for plugins: discover, load what the tree uses, report what is missing.

Called by `coral.executor.running` before the tree is built. Pure of ROS; reads the plugin
location and imports behavior modules through `coral.plugins.loading`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import coral
from coral.executor import records
from coral.plugins import discovery, loading


@dataclass
class PluginState:
    """What is loaded so far; `record()` is the `plugins` status record for it."""

    used: set[str]
    builtin_ids: set[str]
    loaded: dict[str, str] = field(default_factory=dict)  # node ID -> component
    load_errors: dict[str, str] = field(default_factory=dict)  # component -> reason
    report: discovery.DiscoveryReport = field(default_factory=discovery.DiscoveryReport)
    plugins_ready: records.Condition | None = None

    def components_in_use(self) -> set[str]:
        return set(self.loaded.values())

    def record(self) -> dict[str, Any]:
        by_component: dict[str, list[str]] = {}
        for node_id, component in sorted(self.loaded.items()):
            by_component.setdefault(component, []).append(node_id)
        refused = [{"plugin": r.folder, "reason": r.reason} for r in self.report.refused]
        refused += [{"plugin": name, "reason": reason} for name, reason in sorted(self.load_errors.items())]
        return {
            "event": "plugins",
            "loaded": [{"component": name, "behaviors": ids} for name, ids in sorted(by_component.items())],
            "available": sorted(p.name for p in self.report.plugins),
            "refused": refused,
            "conflicts": [
                {"node_id": c.node_id, "kept": c.kept, "dropped": c.dropped, "message": c.describe()}
                for c in self.report.conflicts
            ],
        }


def refresh(state: PluginState, registry: Any, plugins_root: Path, ros_distro: str) -> None:
    """Rescans the plugin location and registers newly available node types the tree uses."""
    state.report = discovery.discover(
        plugins_root,
        ros_distro=ros_distro,
        coral_version=coral.__version__,
        builtin_ids=state.builtin_ids,
    )
    wanted: dict[str, set[str]] = {}
    plugins: dict[str, discovery.Plugin] = {}
    for node_id, (plugin, _entry) in state.report.providers.items():
        if node_id in state.used and node_id not in state.loaded:
            wanted.setdefault(plugin.name, set()).add(node_id)
            plugins[plugin.name] = plugin
    for name, node_ids in sorted(wanted.items()):
        try:
            classes = loading.load_classes(plugins[name], node_ids)
        except loading.PluginLoadError as err:
            state.load_errors[name] = str(err)
            continue
        state.load_errors.pop(name, None)
        for node_id, cls in sorted(classes.items()):
            registry.register(node_id, cls, source=name)
            state.loaded[node_id] = name
