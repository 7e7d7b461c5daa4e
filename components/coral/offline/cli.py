"""The `coral offline-agent` verb: the robot's offline agent (docs/offline.md)."""

from __future__ import annotations

import json
import logging
from pathlib import Path

import click
from coral_core import offline

ROBOT = click.option("--robot", required=True, help="This robot's Node name.")
KUBECONFIG = click.option(
    "--kubeconfig",
    type=click.Path(path_type=Path, dir_okay=False, exists=True),
    required=True,
    help="The kubelet's kubeconfig (the agent acts with the robot's own identity).",
)
ROOT = click.option(
    "--root", type=click.Path(path_type=Path, file_okay=False), default=offline.ROOT, show_default=True
)
STATIC_DIR = click.option(
    "--static-pod-dir",
    "static_dir",
    type=click.Path(path_type=Path, file_okay=False),
    default=offline.STATIC_POD_DIR,
    show_default=True,
    help="The kubelet's staticPodPath.",
)


def _agent(robot: str, kubeconfig: Path, root: Path, static_dir: Path):  # noqa: ANN202 - lazy import
    from coral.offline.agent import Agent

    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(levelname)s %(message)s")
    return Agent(robot=robot, kubeconfig=kubeconfig, root=root, static_dir=static_dir)


@click.group("offline-agent")
def offline_agent_command() -> None:
    """Run the robot's last revision when it boots without the API server."""


@offline_agent_command.command("boot")
@ROBOT
@KUBECONFIG
@ROOT
@STATIC_DIR
def boot(robot: str, kubeconfig: Path, root: Path, static_dir: Path) -> None:
    """Before the kubelet starts: write the verified last revision as static pods when offline."""
    report = _agent(robot, kubeconfig, root, static_dir).boot()
    click.echo(json.dumps(report, sort_keys=True))


@offline_agent_command.command("watch")
@ROBOT
@KUBECONFIG
@ROOT
@STATIC_DIR
@click.option("--interval", type=float, default=1.0, show_default=True)
def watch(robot: str, kubeconfig: Path, root: Path, static_dir: Path, interval: float) -> None:
    """For the robot's life: record what runs, hand over after an offline boot, report."""
    _agent(robot, kubeconfig, root, static_dir).watch(interval)
