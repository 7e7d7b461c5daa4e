"""`coral dev-cluster local`: run the local control plane by hand (up, down, status, robots, demo).

Thin verbs over `controlplane` and `client.Cluster`; `coral_testbed.devcluster` lists the group.
Progress goes to stderr and the kubeconfig path to stdout, so
`export KUBECONFIG=$(coral dev-cluster local up)` works.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from pathlib import Path
from typing import Any

import click
from coral_core import terminal

from coral_testbed import clierrors, clilines
from coral_testbed.cluster import binaries, controlplane, demo
from coral_testbed.cluster.client import Cluster


def dir_option(command: Callable[..., Any]) -> Callable[..., Any]:
    """The state-folder option shared by every verb."""

    @click.option(
        "--dir",
        "state_dir",
        type=click.Path(file_okay=False, path_type=Path),
        default=controlplane.default_state_dir,
        show_default="~/.cache/coral-on-kubernetes/dev-cluster",
        help="Folder holding the control plane's certificates, data, logs and state.",
    )
    @functools.wraps(command)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        return command(*args, **kwargs)

    return wrapper


_fail_on_errors = clierrors.fail_on(
    controlplane.ControlPlaneError,
    binaries.BinariesMissing,
    ValueError,
)


def on_running_cluster(command: Callable[..., Any]) -> Callable[..., Any]:
    """For verbs acting on a running control plane: the `--dir` option, the `Cluster` found there
    passed first, and the testbed's errors (none running, say) as a clean message."""

    @dir_option
    @_fail_on_errors
    @functools.wraps(command)
    def wrapper(state_dir: Path, **kwargs: Any) -> Any:
        return command(Cluster.from_dev_cluster(state_dir), **kwargs)

    return wrapper


@click.group("local")
def local() -> None:
    """The suite's own control plane: etcd, kube-apiserver and controllers as processes of this host,
    with kwok robots (testbed/coral_testbed/cluster/README.md)."""


@local.command()
@dir_option
@click.option(
    "--kwok-robots", "kwok_count", type=click.IntRange(min=0), default=0, help="kwok robot Nodes to create."
)
@click.option(
    "--kwok-prefix", default="kwok-robot-", show_default=True, help="kwok robots are named PREFIX1..PREFIXN."
)
@clilines.labels_option("KEY=VALUE label for every robot.")
@_fail_on_errors
def up(state_dir: Path, kwok_count: int, kwok_prefix: str, labels: dict[str, str]) -> None:
    """Start the control plane in the background; print the kubeconfig path once the API is healthy."""
    try:
        state = controlplane.start(state_dir, progress=clilines.say)
    except controlplane.AlreadyRunning as running:
        clilines.say(str(running))
        state = controlplane.load_state(state_dir.resolve())  # type: ignore[assignment]
    cluster = Cluster(state.kubeconfig, state.layout.bin_dir, is_local=True, state_dir=state.layout.state_dir)
    if kwok_count:
        names = [f"{kwok_prefix}{i}" for i in range(1, kwok_count + 1)]
        clilines.say(f"Creating {kwok_count} kwok robots {names[0]}..{names[-1]}")
        cluster.add_robots(names, labels)
    click.echo(str(state.kubeconfig))


@local.command()
@dir_option
@_fail_on_errors
def down(state_dir: Path) -> None:
    """Stop every process the control plane started."""
    stopped = controlplane.stop(state_dir, progress=clilines.say)
    clilines.say(f"Stopped {len(stopped)} processes" if stopped else f"Nothing was running from {state_dir}")


@local.command()
@dir_option
@_fail_on_errors
def status(state_dir: Path) -> None:
    """Show each component's pid and health, and the kubeconfig path; exit 1 unless all are healthy."""
    report = controlplane.status(state_dir)
    if not report["components"]:
        click.echo(f"not running (state folder {report['state_dir']})")
        raise SystemExit(1)
    rows = [
        [r["name"], str(r["pid"]), terminal.health_text(r["healthy"], r["alive"]), r["log"]]
        for r in report["components"]
    ]
    terminal.console().print(terminal.table(["COMPONENT", "PID", "HEALTH", "LOG"], rows, right=["PID"]))
    click.echo(f"server      {report['server']}")
    click.echo(f"kubeconfig  {report['kubeconfig']}")
    if not report["healthy"]:
        raise SystemExit(1)


@local.group()
def robots() -> None:
    """Create, remove and fail robots (kwok Nodes)."""


def _robot_names(command: Callable[..., Any]) -> Callable[..., Any]:
    """The NAMES argument and `--label` options of the verbs that add robots."""
    command = clilines.labels_option("KEY=VALUE label for the robots.")(command)
    return click.argument("names", nargs=-1, required=True)(command)


@robots.command("add")
@on_running_cluster
@_robot_names
def add_robots(cluster: Cluster, names: tuple[str, ...], labels: dict[str, str]) -> None:
    """Create robots (or add labels to existing ones) and wait until they are Ready."""
    cluster.add_robots(list(names), labels)


@robots.command("remove")
@on_running_cluster
@click.argument("names", nargs=-1, required=True)
def remove_robots(cluster: Cluster, names: tuple[str, ...]) -> None:
    """Delete robots' Nodes."""
    cluster.remove_robots(list(names))


@robots.command("ready")
@on_running_cluster
@click.argument("name")
@click.option("--not-ready", is_flag=True, help="Make the robot report Ready=False instead.")
def robot_ready(cluster: Cluster, name: str, not_ready: bool) -> None:
    """Make a robot report Ready (or NotReady with --not-ready) and wait until its Node shows it."""
    cluster.set_robot_ready(name, not not_ready)


ONE_ROBOT_ACTIONS: dict[str, Callable[[Cluster, str], None]] = {
    "offline": lambda cluster, name: cluster.set_robot_reachable(name, False),
    "online": lambda cluster, name: cluster.set_robot_reachable(name, True),
}
"""`robots VERB NAME`: what each verb does to robot NAME of the running cluster."""

ONE_ROBOT_HELP = {
    "offline": "Take a robot off the network: its lease lapses and it turns Ready=Unknown (about 30 s).",
    "online": "Bring an offline robot back: kwok renews its lease and it reports Ready again.",
}


def _one_robot_command(verb: str) -> click.Command:
    act = ONE_ROBOT_ACTIONS[verb]

    @on_running_cluster
    @click.argument("name")
    def command(cluster: Cluster, name: str) -> None:
        act(cluster, name)

    return click.command(verb, help=ONE_ROBOT_HELP[verb])(command)


for _verb in ONE_ROBOT_ACTIONS:
    robots.add_command(_one_robot_command(_verb))


@local.command("demo")
@_fail_on_errors
def demo_command() -> None:
    """Start a throwaway control plane, schedule a pod onto a robot, show it Running, stop everything."""
    demo.run(echo=click.echo)
