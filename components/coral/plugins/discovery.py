"""Scans the plugin location and decides what an executor may load, and why not.

Pure apart from reading files. Called by the executor on start and while it waits for missing
node types. Components are visited in name order, so name clashes resolve (and read) the same way
on every run: the first component by name keeps the node ID, the other is reported.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

from coral.plugins import compat, hashing
from coral.plugins import manifest as manifests


@dataclass(frozen=True)
class Plugin:
    path: Path
    manifest: manifests.PluginManifest

    @property
    def name(self) -> str:
        return self.manifest.component.name

    @property
    def ready(self) -> bool:
        return (self.path / manifests.READY_NAME).exists()


@dataclass(frozen=True)
class Refusal:
    folder: str
    reason: str

    def describe(self) -> str:
        return f"plugin {self.folder} refused: {self.reason}"


@dataclass(frozen=True)
class Conflict:
    node_id: str
    kept: str  # component name, or "builtin"
    dropped: str

    def describe(self) -> str:
        return (
            f"node ID {self.node_id} is exported by both {self.kept} and {self.dropped}; "
            f"using {self.kept}" + (" (built in)" if self.kept == "builtin" else " (first by component name)")
        )


@dataclass
class DiscoveryReport:
    plugins: list[Plugin] = field(default_factory=list)
    refused: list[Refusal] = field(default_factory=list)
    conflicts: list[Conflict] = field(default_factory=list)
    # node ID -> (plugin, behavior entry) after clash resolution
    providers: dict[str, tuple[Plugin, manifests.BehaviorEntry]] = field(default_factory=dict)

    def provided_ids(self) -> set[str]:
        return set(self.providers)


def inspect_plugin(folder: Path, *, ros_distro: str, coral_version: str) -> Plugin | Refusal:
    """Reads one plugin folder: a loadable `Plugin`, or a `Refusal` saying why not."""
    try:
        manifest = manifests.read_manifest(folder)
    except manifests.ManifestError as err:
        return Refusal(folder.name, str(err))
    if manifest.component.name != folder.name:
        return Refusal(
            folder.name, f"manifest names component {manifest.component.name}, folder is {folder.name}"
        )
    reason = compat.incompatibility(manifest, coral_version=coral_version, ros_distro=ros_distro)
    if reason is None:
        reason = hashing.verify(folder, manifest.files)
    if reason is not None:
        return Refusal(folder.name, reason)
    for entry in manifest.behaviors:
        if f"{manifests.BEHAVIORS_DIR}/{entry.module.replace('.', '/')}.py" not in manifest.files:
            return Refusal(
                folder.name, f"behavior {entry.id} names module {entry.module}, which was not exported"
            )
    return Plugin(folder, manifest)


def discover(
    plugins_root: Path,
    *,
    ros_distro: str,
    coral_version: str,
    builtin_ids: Iterable[str] = (),
) -> DiscoveryReport:
    report = DiscoveryReport()
    if not plugins_root.is_dir():
        return report
    builtins = set(builtin_ids)
    # Hidden folders are exports in progress or retired ones (see exporting._swap_into_place).
    folders = sorted(p for p in plugins_root.iterdir() if p.is_dir() and not p.name.startswith("."))
    for folder in folders:
        result = inspect_plugin(folder, ros_distro=ros_distro, coral_version=coral_version)
        if isinstance(result, Refusal):
            report.refused.append(result)
            continue
        report.plugins.append(result)
        for entry in result.manifest.behaviors:
            if entry.id in builtins:
                report.conflicts.append(Conflict(entry.id, "builtin", result.name))
            elif entry.id in report.providers:
                report.conflicts.append(Conflict(entry.id, report.providers[entry.id][0].name, result.name))
            else:
                report.providers[entry.id] = (result, entry)
    return report
