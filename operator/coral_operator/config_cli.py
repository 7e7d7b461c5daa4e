"""`coral config SYSTEM ROBOT`: what one robot of a CoralSystem runs, with its overrides resolved and
validated. A thin verb over `robot_config`; loaded lazily by `coral_core.command`."""

from __future__ import annotations

import json

import click
from coral_core import terminal

from coral_operator import robot_config


def render(said: robot_config.RobotConfig) -> str:
    """The configuration as plain text: where it stands, components, parameters, tree."""
    lines = [f"coralsystem/{said.system} robot {said.robot}"]
    lines.append(f"  overrides: {', '.join(said.overrides) or 'none match'}")
    if said.problems:
        lines.append("  INVALID: the robot keeps what it runs")
        lines += [f"    {problem}" for problem in said.problems]
    else:
        lines.append(f"  configHash: {said.config_hash}")
    if said.running_hash is None:
        lines.append("  running: no CoralInstance yet")
    else:
        state = (
            "this configuration" if said.runs_it else f"configuration {said.running_hash}, not this one yet"
        )
        lines.append(f"  running: {state} (revision {said.running_revision})")
    if said.components:
        lines.append("components:")
        for component in said.components:
            env = ", ".join(f"{k}={v}" for k, v in component.env.items())
            lines.append(
                f"  {component.kind[:-1]:<9} {component.name:<20} {component.image}"
                + (f"  [{env}]" if env else "")
            )
        lines.append("parameters:")
        lines += [f"  {line}" for line in said.parameters.rstrip("\n").splitlines()]
        main = f" (main tree {said.main_tree_id})" if said.main_tree_id else ""
        lines.append(f"tree.xml{main}:")
        lines += [f"  {line}" for line in said.tree.rstrip("\n").splitlines()]
        for name, text in sorted(said.tree_files.items()):
            lines.append(f"{name}:")
            lines += [f"  {line}" for line in text.rstrip("\n").splitlines()]
    return "\n".join(lines)


@click.command("config")
@click.argument("system")
@click.argument("robot")
@click.option("-n", "--namespace", default="default", show_default=True)
@click.option("-o", "--output", type=click.Choice(["text", "json"]), default="text", show_default=True)
def config_command(system: str, robot: str, namespace: str, output: str) -> None:
    """Print what ROBOT runs in SYSTEM: components, parameters and tree, with the overrides that
    match it resolved and validated as the operator does. Exits 1 when the configuration is invalid."""
    try:
        said = robot_config.ConfigReader.from_kubeconfig(namespace).read(system, robot)
    except robot_config.ConfigReadError as error:
        raise click.ClickException(str(error)) from error
    if output == "json":
        click.echo(json.dumps(said.to_json(), indent=2))
    else:
        terminal.console().print(render(said), markup=False, highlight=False)
    if not said.valid:
        raise click.exceptions.Exit(1)
