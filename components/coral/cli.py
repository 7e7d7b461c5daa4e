"""The `coral` command: a click group of thin verbs, each loaded only when it is called.

Verbs live in their own modules and are listed in `VERBS`, so importing the CLI never drags in
rclpy or the Kubernetes client unless the chosen verb needs it.
"""

from __future__ import annotations

import importlib
from typing import Any

import click

# verb name -> "module:attribute" of a click command.
VERBS: dict[str, str] = {
    "dev-cluster": "coral_testbed.cluster.cli:dev_cluster",
}


class LazyGroup(click.Group):
    """A click group that imports a verb's module only when that verb is used."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted(VERBS)

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        target = VERBS.get(cmd_name)
        if target is None:
            return None
        module_name, attribute = target.split(":")
        command: Any = getattr(importlib.import_module(module_name), attribute)
        return command


@click.group(cls=LazyGroup)
@click.version_option(package_name="coral-on-kubernetes")
def main() -> None:
    """Coral on Kubernetes: compose robot software from drivers, skillsets and executors."""
