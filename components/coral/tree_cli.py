"""The `coral tree` verbs: `coral tree watch` draws a live tree read over BT.CPP's Groot2 protocol
(an executor started with `--groot2-port`, or any BT.CPP program with a `Groot2Publisher`)."""

from __future__ import annotations

import json
import sys
import time

import click


@click.group("tree")
def tree_group() -> None:
    """Live behavior trees over Groot2's protocol."""


@tree_group.command("watch")
@click.option("--host", default="127.0.0.1", show_default=True, help="Address of the Groot2 publisher.")
@click.option("--port", default=1667, show_default=True, type=click.IntRange(1, 65535), help="Its REP port.")
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
    host: str, port: int, once: bool, as_json: bool, blackboards: bool, interval: float, timeout: float
) -> None:
    """Draw the live tree of a Groot2 publisher in the terminal (rich)."""
    from coral_core.bt.groot2.client import Groot2Client, Groot2Error
    from coral_core.bt.groot2.watching import Watcher, render
    from rich.console import Console
    from rich.live import Live

    if as_json and not once:
        raise click.UsageError("--json needs --once")
    with Groot2Client(host, port, timeout_s=timeout) as client:
        watcher = Watcher(client)
        try:
            snapshot = watcher.snapshot(blackboards)
        except (Groot2Error, ValueError) as err:
            raise click.ClickException(f"cannot read a tree from {host}:{port}: {err}") from err
        if once:
            if as_json:
                json.dump(snapshot, sys.stdout, indent=2)
                sys.stdout.write("\n")
            else:
                Console().print(render(snapshot))
            return
        with Live(render(snapshot), refresh_per_second=max(1, int(1 / interval))) as live:
            while True:
                time.sleep(interval)
                try:
                    live.update(render(watcher.snapshot(blackboards)))
                except Groot2Error as err:
                    live.console.print(f"[red]{err}[/red]")
