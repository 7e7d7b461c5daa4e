"""`coral groot2 SYSTEM ROBOT`: a robot's live tree on localhost for Groot2, forwarded from its
executor's pod through the API server (docs/groot2.md). `forwarded` is shared with
`coral tree watch SYSTEM ROBOT` (`coral_operator.tree_cli`). Loaded lazily by `coral_core.command`.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from contextlib import contextmanager

import click
from coral_core.command import stop_on_ctrl_c

from coral_operator import groot2_target, port_forwarding, user_client
from coral_operator.api.components import GROOT2_DEFAULT_PORT


@contextmanager
def forwarded(
    *, namespace: str, system: str, robot: str, executor: str | None, local_ports: list[int]
) -> Iterator[tuple[groot2_target.Target, port_forwarding.PortForward]]:
    """Forward the robot's publisher ports (its port, then the next, as many as `local_ports`) to
    `local_ports` on 127.0.0.1 (0 takes a free one); errors become `click.ClickException`s."""
    api = user_client.user_api_client()
    try:
        target = groot2_target.read_target(api, namespace, system, robot, executor)
    except groot2_target.TargetError as error:
        raise click.ClickException(str(error)) from error
    forward = port_forwarding.PortForward(
        api_client=api,
        namespace=namespace,
        pod=target.pod,
        pairs=[(local, target.port + offset) for offset, local in enumerate(local_ports)],
        on_error=lambda message: click.echo(f"Error: {message}", err=True),
    )
    try:
        forward.start()
    except OSError as error:
        raise click.ClickException(f"cannot listen on 127.0.0.1:{local_ports}: {error.strerror}") from error
    try:
        yield target, forward
    finally:
        forward.close()


@click.command("groot2")
@click.argument("system")
@click.argument("robot")
@click.option("-n", "--namespace", default="default", show_default=True)
@click.option(
    "--port",
    default=GROOT2_DEFAULT_PORT,
    show_default=True,
    type=click.IntRange(1, 65534),
    help="Local port for Groot2; the next one carries the breakpoints it is told of.",
)
@click.option("--executor", default=None, help="The executor to watch, when several publish.")
def groot2_command(system: str, robot: str, namespace: str, port: int, executor: str | None) -> None:
    """Forward ROBOT's live tree of SYSTEM to localhost for Groot2, through the API server.

    Forwards the executor's Groot2 ports (its `groot2.port` and the next) from its pod, as
    `kubectl port-forward` does: your credentials, RBAC (`create` on `pods/portforward`) and the
    audit log apply. Connect Groot2's Monitor to localhost and PORT. Ctrl-C stops.

    Forwarding sends no request of its own: an executor holding its first tick for a debugger
    (`groot2.waitForClientSeconds`) goes on waiting until Groot2 connects.
    """
    stop_on_ctrl_c()
    with forwarded(
        namespace=namespace, system=system, robot=robot, executor=executor, local_ports=[port, port + 1]
    ) as (target, _forward):
        click.echo(
            f"Forwarding {target.executor} of robot {robot} (pod {target.pod}, ports {target.port} and "
            f"{target.port + 1}) to 127.0.0.1:{port} and {port + 1}."
        )
        click.echo(f"Connect Groot2 (Monitor) to localhost, port {port}. Ctrl-C stops.")
        try:
            threading.Event().wait()
        except KeyboardInterrupt:
            click.echo("Stopped forwarding.")
