"""`coral robot-runner`: run the pods of simulated robots as local processes until interrupted.

Test and demo tooling: acts as the kubelet of the named robots (or of every Node labelled
`coral.dev/robot`) in the cluster of $KUBECONFIG. Thin verb over `runner.RobotRunner`.
"""

from __future__ import annotations

import logging
import shlex
import signal
import threading
from pathlib import Path
from types import FrameType

import click

from coral_testbed.runner import network


def parse_image_commands(values: tuple[str, ...]) -> dict[str, list[str]]:
    """`IMAGE=python -m module` pairs -> {image: argv}."""
    mapping: dict[str, list[str]] = {}
    for value in values:
        image, sep, command = value.partition("=")
        if not sep or not image or not command.strip():
            raise click.BadParameter(f"{value!r}: expected IMAGE=COMMAND", param_hint="--image-command")
        mapping[image] = shlex.split(command)
    return mapping


@click.command("robot-runner")
@click.argument("robots", nargs=-1)
@click.option(
    "--kubeconfig", type=click.Path(exists=True, dir_okay=False, path_type=Path), envvar="KUBECONFIG"
)
@click.option("--root", type=click.Path(file_okay=False, path_type=Path), help="Folder for robot files.")
@click.option("--adopt", is_flag=True, help="Take over robots kwok simulates (their Nodes are re-created).")
@click.option("--no-isolate", is_flag=True, help="Share the host network instead of one namespace per robot.")
@click.option("--image-command", multiple=True, metavar="IMAGE=COMMAND", help="Entrypoint of an image.")
@click.option("--cleanup", is_flag=True, help="Only remove what crashed runners left behind, then exit.")
@click.option("-v", "--verbose", is_flag=True)
def robot_runner(
    robots: tuple[str, ...],
    kubeconfig: Path | None,
    root: Path | None,
    adopt: bool,
    no_isolate: bool,
    image_command: tuple[str, ...],
    cleanup: bool,
    verbose: bool,
) -> None:
    """Run the pods bound to simulated robots as local processes (test and demo tooling)."""
    logging.basicConfig(level=logging.INFO if verbose else logging.WARNING, format="%(asctime)s %(message)s")
    if cleanup:
        freed = network.cleanup_stale()
        click.echo(f"Removed leftovers of slots {freed}" if freed else "Nothing to clean up")
        return
    if kubeconfig is None:
        raise click.UsageError("no cluster: set KUBECONFIG or pass --kubeconfig")
    entrypoints = parse_image_commands(image_command)

    from kubernetes import client as k8s
    from kubernetes import config as k8s_config
    from kubernetes.client.exceptions import ApiException

    from coral_testbed.runner import nodes
    from coral_testbed.runner.runner import LINK_ANNOTATION, RobotRunner

    api = k8s_config.new_client_from_config(config_file=str(kubeconfig))
    names = list(robots)
    if not names:
        listed = k8s.CoreV1Api(api).list_node(label_selector=nodes.ROBOT_LABEL)
        names = sorted(node.metadata.name for node in listed.items)
        if not names:
            raise click.UsageError(f"no robots named and no Node labelled {nodes.ROBOT_LABEL}")
    done = threading.Event()

    def on_signal(signum: int, frame: FrameType | None) -> None:
        done.set()

    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)
    runner = RobotRunner(api, names, root=root, isolate=not no_isolate, adopt=adopt, entrypoints=entrypoints)
    try:
        runner.start()
    except nodes.AdoptionRefused as error:
        raise click.ClickException(str(error)) from error
    try:
        mode = "one network namespace each" if runner.isolated else "shared host network"
        click.echo(f"Robot runner ready: robots {', '.join(names)}; files in {runner.root}; {mode}", err=True)
        for name in names:
            click.echo(f"  {name}: {runner.address(name)}", err=True)
        click.echo(
            f"Cut a robot's link with: kubectl annotate node NAME {LINK_ANNOTATION}=down --overwrite",
            err=True,
        )
        while not done.wait(1.0):
            try:
                runner.apply_link_annotations()
            except ApiException as error:
                logging.getLogger(__name__).warning("Link annotations not read: %s", error.reason)
    finally:
        runner.stop()
        api.close()
        click.echo("Robot runner stopped", err=True)
