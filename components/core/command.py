"""The `coral` command: a click group of thin verbs, each loaded only when it is called.

Each installed part of the project registers its verbs as entry points of the group `coral.verbs`
(setup.py, beside the part's source root), so a verb whose part is not installed, such as the
testbed's inside a component image, is not offered. Loading a verb only when it is chosen keeps
rclpy and the Kubernetes client out of every other verb.
"""

from __future__ import annotations

import signal
import threading
from importlib import metadata

import click

VERB_GROUP = "coral.verbs"


def installed_verbs() -> dict[str, metadata.EntryPoint]:
    """The verbs of every installed part, by name."""
    return {entry.name: entry for entry in metadata.entry_points(group=VERB_GROUP)}


def stop_on_ctrl_c() -> None:
    """Make Ctrl-C (SIGINT) raise KeyboardInterrupt in a verb that runs until it comes, also when
    the process started with SIGINT ignored: a shell starts its background jobs so, and Python then
    installs no handler, so a supervisor's or a script's SIGINT would never stop the verb. Go
    programs that wait for the signal take it back the same way."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.default_int_handler)


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
