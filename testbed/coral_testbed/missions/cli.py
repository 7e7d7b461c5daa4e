"""The `coral demo` verb: a mission applied with kubectl on a throwaway kind cluster (see demo.py)."""

from __future__ import annotations

import sys
from pathlib import Path

import click
from coral.local.cli import TREE_PNG, output_option


@click.command("demo")
@click.option(
    "--mission",
    type=click.Choice(["slam", "relay", "site"]),
    default="slam",
    show_default=True,
    help="slam: examples/lidar-slam on one robot; relay: examples/relay on three; "
    "site: examples/site on a mixed fleet of four.",
)
@click.option(
    "--scans",
    type=click.IntRange(min=10),
    default=None,
    help="Bag length (default: 300 slam, 60 relay and site).",
)
@click.option("--timeout", type=float, default=600.0, show_default=True, help="Seconds the mission may take.")
@TREE_PNG
@output_option(Path("out/demo"), "Where the SLAM map, trajectory and picture are kept after the demo.")
def demo_command(
    mission: str, scans: int | None, timeout: float, tree_png: Path | None, output_dir: Path
) -> None:
    """Start a kind cluster whose workers are the robots and the operator by Helm; kubectl apply a
    mission, follow it; delete the cluster."""
    from coral_testbed.missions import demo

    try:
        outcome = demo.run(
            mission,
            scans or (300 if mission == "slam" else 60),
            timeout,
            echo=click.echo,
            tree_png=tree_png,
            output_dir=output_dir,
        )
    except demo.DemoUnsupported as error:
        raise click.ClickException(str(error)) from error
    sys.exit(0 if outcome.success else 1)
