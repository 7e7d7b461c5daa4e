"""`coral logs SYSTEM`: the logs of every robot of a CoralSystem, through the API server.

A thin verb over `fleet_logs`, offered through `coral_core.logs_verb` (which also serves a local
run's logs under the same verb) as `LOGS_OF_SYSTEMS`.
"""

from __future__ import annotations

import os
import sys

import click
from coral_core import logs_verb
from coral_core.command import stop_on_ctrl_c
from kubernetes import config as k8s_config
from kubernetes.client.exceptions import ApiException

from coral_operator import fleet_logs, user_client

# What a shell reports for a command ended by Ctrl-C (128 + SIGINT).
INTERRUPTED_EXIT = 130


def _since(ctx: click.Context, param: click.Parameter, value: str | None) -> int | None:
    if value is None:
        return None
    try:
        return fleet_logs.parse_since(value)
    except ValueError as error:
        raise click.BadParameter(str(error), ctx=ctx, param=param) from None


@click.command("logs")
@click.argument("system")
@click.option("-n", "--namespace", default="default", show_default=True)
@click.option("--robot", default=None, help="Only this robot (its coral.dev/robot label).")
@click.option("--component", "-c", default=None, help="Only this component (its container's name).")
@click.option("--follow", "-f", is_flag=True, help="Keep printing new lines, also of pods that start later.")
@click.option(
    "--since", "since_s", default=None, callback=_since, help="Only lines newer than this (30s, 5m, 1h)."
)
@click.option(
    "--color",
    type=click.Choice(["auto", "always", "never"]),
    default="auto",
    show_default=True,
    help="Colour the robot and component (auto: on a terminal only).",
)
def logs_command(
    system: str,
    namespace: str,
    robot: str | None,
    component: str | None,
    follow: bool,
    since_s: int | None,
    color: str,
) -> None:
    """Print the logs of every robot of coralsystem/SYSTEM, each line prefixed robot/component.

    Lines of one container keep their order; containers interleave as their lines arrive. With
    -f it follows until Ctrl-C.
    """
    if follow:
        stop_on_ctrl_c()
    colour = color == "always" or (color == "auto" and sys.stdout.isatty())
    width = 0

    def print_line(stream: fleet_logs.Stream, line: str) -> None:
        nonlocal width
        width = max(width, len(stream.robot) + 1 + len(stream.component))
        click.echo(fleet_logs.prefixed(stream, line, width, colour), color=colour)

    try:
        reader = fleet_logs.FleetLogs(
            api_client=user_client.user_api_client(),
            namespace=namespace,
            system=system,
            robot=robot,
            component=component,
            since_s=since_s,
        )
        reader.check_system()
        read = reader.run(follow, print_line)
    except fleet_logs.LogsError as error:
        raise click.ClickException(str(error)) from error
    except k8s_config.ConfigException as error:
        raise click.ClickException(f"no cluster to read from: {error}") from error
    except ApiException as error:
        raise click.ClickException(f"the API server refused: {error.status} {error.reason}") from error
    except KeyboardInterrupt:
        # Ctrl-C is how one stops following: end quietly, as `kubectl logs -f` does.
        sys.exit(INTERRUPTED_EXIT)
    except BrokenPipeError:
        # The reader of a pipe stopped (`| head`): nothing more to say to anyone.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        sys.exit(0)
    if not read:
        click.echo(f"coralsystem/{system} has no started containers to read", err=True)


LOGS_OF_SYSTEMS = logs_verb.LogsSource(command=logs_command, claims=None)
"""`coral logs SYSTEM`: registered in `coral_core.logs_verb.LOGS_GROUP` (setup.py)."""
