"""`coral dev-cluster setup|up|down|robots`: a kind cluster of robots (docs/kind.md).

Thin verbs over `provisioning`, `clusters` and `faults`; `coral_testbed.devcluster` lists them.
Progress goes to stderr and the kubeconfig path to stdout, so
`export KUBECONFIG=$(coral dev-cluster up --robots 2)` works.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

import click

from coral_testbed import clierrors, clilines, images
from coral_testbed.cluster import binaries, controlplane
from coral_testbed.kind import clusters, engine, faults, noderootfs, provisioning

_fail_on_errors = clierrors.fail_on(
    provisioning.SetupError,
    engine.EngineError,
    noderootfs.NodeImageError,
    clusters.ClusterError,
    faults.FaultError,
    images.ImageBuildError,
    binaries.BinariesMissing,
    controlplane.ControlPlaneError,
    ValueError,
)


def _name_option(command: Callable[..., Any]) -> Callable[..., Any]:
    return click.option(
        "--name", default=clusters.DEFAULT_NAME, show_default=True, help="The kind cluster's name."
    )(command)


@click.command()
@_fail_on_errors
def setup() -> None:
    """Install what kind needs where missing: Docker engine, kind, node binaries, node image."""
    ready = provisioning.ensure(clilines.say)
    clilines.say(f"kind is ready: node image {ready.node_image}")
    # Setup caches; it leaves no engine running without a cluster. `up` starts it again (seconds).
    clusters.stop_engine_unless_used(ready.engine)


@click.command()
@_name_option
@click.option(
    "--robots",
    "count",
    type=click.IntRange(min=0),
    default=1,
    show_default=True,
    help="Robots: kind workers labelled coral.dev/robot=PREFIXi.",
)
@click.option(
    "--robot-prefix", default="robot-", show_default=True, help="Robots are named PREFIX1..PREFIXN."
)
@click.option(
    "--kwok-robots",
    "kwok_count",
    type=click.IntRange(min=0),
    default=0,
    help="Simulated robots: kwok Nodes, kwok running against kind's API server.",
)
@clilines.labels_option("KEY=VALUE label for every robot.")
@_fail_on_errors
def up(name: str, count: int, robot_prefix: str, kwok_count: int, labels: dict[str, str]) -> None:
    """Create the kind cluster (set up first if needed); print its kubeconfig path."""
    from coral_testbed.cluster.client import Cluster

    ready = provisioning.ensure(clilines.say)
    running = clusters.load(name, ready.engine)
    if running is None:
        robots = {f"{robot_prefix}{i}": dict(labels) for i in range(1, count + 1)}
        running = clusters.create(name, robots, ready.engine, ready.node_image, clilines.say)
    else:
        clilines.say(f"kind cluster {name} exists already")
    if kwok_count:
        clusters.start_kwok(running)
        names = [f"kwok-{robot_prefix}{i}" for i in range(1, kwok_count + 1)]
        clilines.say(f"Creating {kwok_count} kwok robots {names[0]}..{names[-1]}")
        Cluster(running.kubeconfig, None, is_local=False).add_robots(names, labels)
    click.echo(str(running.kubeconfig))


@click.command()
@_name_option
@click.option(
    "--keep-engine",
    is_flag=True,
    help="Leave the project's dockerd running (node image stays cached either way).",
)
@_fail_on_errors
def down(name: str, keep_engine: bool) -> None:
    """Delete the kind cluster, its registry, kwok and network; stop the project's dockerd."""
    node_engine = engine.start(clilines.say)
    clusters.delete(name, node_engine, clilines.say)
    if node_engine.owned and not keep_engine:
        if clusters.stop_engine_unless_used(node_engine):
            clilines.say("Stopped the project's dockerd")
        else:
            clilines.say("Other kind clusters still run on the project's dockerd; leaving it running")


FAULTS: dict[str, Callable[[clusters.Running, str], object]] = {
    "stop": faults.stop_kubelet,
    "start": faults.start_kubelet,
    "kill-containerd": faults.kill_containerd,
    "power-cycle": faults.power_cycle,
    "reboot": faults.reboot_in_place,
    "power-off": faults.cut_power,
    "power-on": faults.restore_power,
    "cut": faults.cut_link,
    "restore": faults.restore_link,
}


def _on_cluster(command: Callable[..., Any]) -> Callable[..., Any]:
    """For verbs acting on a robot of a running cluster: `--name`, ROBOT, the cluster found."""

    @_name_option
    @click.argument("robot")
    @_fail_on_errors
    @functools.wraps(command)
    def wrapper(name: str, robot: str, **kwargs: Any) -> Any:
        node_engine = engine.start(clilines.say)
        running = clusters.load(name, node_engine)
        if running is None:
            raise clusters.ClusterError(f"no kind cluster {name}; create it with `coral dev-cluster up`")
        return command(running, robot, **kwargs)

    return wrapper


@click.group()
def robots() -> None:
    """Faults of a robot through its node container: kubelet, containerd, link, power."""


def _fault_command(verb: str) -> click.Command:
    act = FAULTS[verb]

    @_on_cluster
    def command(running: clusters.Running, robot: str) -> None:
        act(running, robot)

    return click.command(verb, help=(act.__doc__ or verb).splitlines()[0])(command)


for _verb in FAULTS:
    robots.add_command(_fault_command(_verb))


COMMANDS = (setup, up, down, robots)
