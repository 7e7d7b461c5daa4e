"""The `coral tree` verbs: `coral tree watch` draws a live tree read over BT.CPP's Groot2 protocol
(an executor started with `--groot2-port`, or any BT.CPP program with a `Groot2Publisher`)."""

from __future__ import annotations

import json
import sys
import time
from dataclasses import dataclass

import click
from coral_core.command import stop_on_ctrl_c


@click.group("tree")
def tree_group() -> None:
    """Live behavior trees over Groot2's protocol."""


@tree_group.command("watch")
@click.argument("robot_of_system", nargs=-1, metavar="[SYSTEM ROBOT]")
@click.option("--host", default=None, help="Address of the Groot2 publisher  [default: 127.0.0.1]")
@click.option("--port", default=1667, show_default=True, type=click.IntRange(1, 65535), help="Its REP port.")
@click.option(
    "-n",
    "--namespace",
    default="default",
    show_default=True,
    help="With SYSTEM ROBOT: the system's namespace.",
)
@click.option("--executor", default=None, help="With SYSTEM ROBOT: the executor, when several publish.")
@click.option("--once", is_flag=True, help="Print one snapshot and exit.")
@click.option("--json", "as_json", is_flag=True, help="Print the snapshot as JSON (with --once).")
@click.option("--blackboards", is_flag=True, help="Include every subtree's blackboard.")
@click.option(
    "--interval", default=0.2, show_default=True, type=click.FloatRange(min=0.02), help="Seconds per refresh."
)
@click.option(
    "--timeout", default=2.0, show_default=True, type=click.FloatRange(min=0.1), help="Per request."
)
def watch_command(
    robot_of_system: tuple[str, ...],
    host: str | None,
    port: int,
    namespace: str,
    executor: str | None,
    once: bool,
    as_json: bool,
    blackboards: bool,
    interval: float,
    timeout: float,
) -> None:
    """Draw the live tree of a Groot2 publisher in the terminal (rich): at --host and --port, or of
    ROBOT in SYSTEM, forwarded from its executor's pod through the API server (as `coral groot2`)."""
    if as_json and not once:
        raise click.UsageError("--json needs --once")
    view = View(once=once, as_json=as_json, blackboards=blackboards, interval=interval, timeout=timeout)
    if not once:
        stop_on_ctrl_c()
    if not robot_of_system:
        host = host or "127.0.0.1"
        _watch(host, port, f"{host}:{port}", view)
        return
    if len(robot_of_system) != 2:
        raise click.UsageError("give both SYSTEM and ROBOT, or neither")
    if host is not None:
        raise click.UsageError("--host and SYSTEM ROBOT exclude each other")
    from coral_operator.groot2_cli import forwarded

    system, robot = robot_of_system
    local = [0]  # a free port: only the request port is read
    with forwarded(namespace=namespace, system=system, robot=robot, executor=executor, local_ports=local) as (
        target,
        forward,
    ):
        where = f"robot {robot} of coralsystem/{system} (pod {target.pod}, port {target.port})"
        _watch("127.0.0.1", forward.local_ports[0], where, view)


@dataclass(frozen=True)
class View:
    """How `coral tree watch` shows the tree."""

    once: bool
    as_json: bool
    blackboards: bool
    interval: float
    timeout: float


def _watch(host: str, port: int, where: str, view: View) -> None:
    from coral_core.bt.groot2.client import Groot2Client, Groot2Error
    from coral_core.bt.groot2.watching import Watcher, render
    from rich.console import Console
    from rich.live import Live

    with Groot2Client(host, port, timeout_s=view.timeout) as client:
        watcher = Watcher(client)
        try:
            snapshot = watcher.snapshot(view.blackboards)
        except (Groot2Error, ValueError) as err:
            raise click.ClickException(f"cannot read a tree from {where}: {err}") from err
        if view.once:
            if view.as_json:
                json.dump(snapshot, sys.stdout, indent=2)
                sys.stdout.write("\n")
            else:
                Console().print(render(snapshot))
            return
        with Live(render(snapshot), refresh_per_second=max(1, int(1 / view.interval))) as live:
            while True:
                time.sleep(view.interval)
                try:
                    live.update(render(watcher.snapshot(view.blackboards)))
                except Groot2Error as err:
                    live.console.print(f"[red]{err}[/red]")
