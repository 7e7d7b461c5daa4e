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
    "run": "coral.local.cli:run_command",
    "ps": "coral.local.cli:ps_command",
    "stop": "coral.local.cli:stop_command",
    "logs": "coral.local.cli:logs_command",
    "validate": "coral.local.cli:validate_command",
    "verify": "coral.local.cli:verify_command",
    "nodes-model": "coral.local.cli:nodes_model_command",
    "generate-bag": "coral.lidar.cli:generate_bag_command",
    "slam-demo": "coral.lidar.cli:slam_demo_command",
    "dev-cluster": "coral_testbed.cluster.cli:dev_cluster",
    "images": "coral_testbed.images.cli:images",
    "executor": "coral.executor.cli:executor_command",
    "tree": "coral.tree_cli:tree_group",
    "groot2": "coral_operator.groot2_cli:groot2_command",
    "skillset": "coral.sdk.cli:skillset_command",
    "plugins": "coral.plugins.cli:plugins_command",
    "operator": "coral_operator.cli:operator_command",
    "convert": "coral_operator.convert.cli:convert_command",
    "crds": "coral_operator.crds_cli:crds_command",
    "rollout": "coral_operator.rollout_cli:rollout",
    "demo": "coral_testbed.missions.cli:demo_command",
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
