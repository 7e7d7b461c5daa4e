"""The `coral plugins` verb: show what a plugin location holds, as an executor would see it."""

from __future__ import annotations

from pathlib import Path

import click

import coral
from coral.plugins import discovery


def _report(plugins_dir: Path) -> discovery.DiscoveryReport:
    from coral.plugins import compat

    return discovery.discover(
        plugins_dir, ros_distro=compat.current_ros_distro(), coral_version=coral.__version__
    )


@click.group("plugins")
def plugins_command() -> None:
    """Inspect exported plugins (manifests, refusals, clashes, Groot2 palette)."""


@plugins_command.command("list")
@click.argument("plugins_dir", type=click.Path(path_type=Path, file_okay=False, exists=True))
def list_plugins(plugins_dir: Path) -> None:
    """List loadable plugins with their behaviors, refused plugins and node ID clashes."""
    report = _report(plugins_dir)
    for plugin in report.plugins:
        ids = ", ".join(entry.id for entry in plugin.manifest.behaviors) or "-"
        state = "ready" if plugin.ready else "not ready"
        click.echo(f"{plugin.name} ({plugin.manifest.component.kind}, {state}): {ids}")
    for refusal in report.refused:
        click.echo(refusal.describe())
    for conflict in report.conflicts:
        click.echo(conflict.describe())


@plugins_command.command("model")
@click.argument("plugins_dir", type=click.Path(path_type=Path, file_okay=False, exists=True))
def model(plugins_dir: Path) -> None:
    """Print the loadable behaviors as a BT.CPP <TreeNodesModel> (Groot2 palette)."""
    from coral_core.bt import treenodesmodel

    from coral.plugins import manifest

    report = _report(plugins_dir)
    palette = manifest.palette_behaviors(p.manifest for p in report.plugins)
    click.echo(treenodesmodel.build_tree_nodes_model(palette), nl=False)
