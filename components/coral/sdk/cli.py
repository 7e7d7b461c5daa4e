"""The `coral skillset` verb (also `python -m coral.sdk.run`): runs one skillset or driver process."""

from __future__ import annotations

import sys
from pathlib import Path

import click


@click.command("skillset")
@click.argument("target", metavar="MODULE:CLASS")
@click.option(
    "--plugins", "plugins_dir", type=click.Path(path_type=Path), help="Plugin location to export into."
)
@click.option(
    "--params", "params_file", type=click.Path(path_type=Path, dir_okay=False), help="ROS parameters YAML."
)
@click.option("--name", default=None, help="Component (and node) name; default: the class's NAME.")
@click.option("--namespace", default=None, help="ROS namespace of the component's node.")
@click.option("--export-only", is_flag=True, help="Export the plugin into --plugins and exit, without ROS.")
def skillset_command(
    target: str,
    plugins_dir: Path | None,
    params_file: Path | None,
    name: str | None,
    namespace: str | None,
    export_only: bool,
) -> None:
    """Run a skillset or driver component: export its behaviors, then serve until SIGINT/SIGTERM."""
    from coral.plugins import exporting
    from coral.sdk import running

    try:
        component_class = running.load_component_class(target)
    except (ImportError, ValueError) as err:
        raise click.UsageError(str(err)) from err
    if export_only:
        if plugins_dir is None:
            raise click.UsageError("--export-only needs --plugins")
        try:
            folder = running.export_component(component_class, plugins_dir, name=name, namespace=namespace)
        except (ValueError, exporting.ExportError) as err:
            click.echo(f"error: {err}", err=True)
            sys.exit(running.EXIT_BAD_INPUT)
        click.echo(f"Exported {folder}")
        return
    sys.exit(
        running.run_component(
            component_class,
            plugins_dir=plugins_dir,
            params_file=params_file,
            name=name,
            namespace=namespace,
        )
    )
