"""The `coral` command: a click group of thin verbs, each loaded only when it is called.

Each installed part of the project registers its verbs as entry points of the group `coral.verbs`
(setup.py, beside the part's source root), so a verb whose part is not installed, such as the
testbed's inside a component image, is not offered. Loading a verb only when it is chosen keeps
rclpy and the Kubernetes client out of every other verb.
"""

from __future__ import annotations

from importlib import metadata

import click

VERB_GROUP = "coral.verbs"


def installed_verbs() -> dict[str, metadata.EntryPoint]:
    """The verbs of every installed part, by name."""
    return {entry.name: entry for entry in metadata.entry_points(group=VERB_GROUP)}


class LazyGroup(click.Group):
    """A click group that imports a verb's module only when that verb is used."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted(installed_verbs())

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        entry = installed_verbs().get(cmd_name)
        if entry is None:
            return None
        command: click.Command = entry.load()
        return command


@click.group(cls=LazyGroup)
@click.version_option(package_name="coral-on-kubernetes")
def main() -> None:
    """Coral on Kubernetes: compose robot software from drivers, skillsets and executors."""
