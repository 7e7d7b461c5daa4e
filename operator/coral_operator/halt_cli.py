"""`coral halt` and `coral resume`: halt the trees of a CoralSystem's robots and let them run again.

Thin verbs over `halt_control`, which writes `spec.halt`. An operational stop, not a safety stop:
the executors stop ticking their trees; drivers and skillsets keep running. Loaded lazily by
`coral_core.command`.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import click
from coral_core import polling
from coral_core.halt import MAX_PARK_SECONDS

from coral_operator import halt_control
from coral_operator.api.system import HaltSpec
from coral_operator.system_cli import system_target


def _target(function: Callable[..., None]) -> Callable[..., None]:
    """SYSTEM, --namespace, --robot, --wait and --timeout, with halt errors shown as clean CLI errors."""
    run = click.option(
        "--timeout",
        "timeout_s",
        type=click.FloatRange(min=0),
        default=60.0,
        show_default=True,
        help="Seconds --wait waits at most.",
    )(function)
    run = click.option("--wait", is_flag=True, help="Wait until every robot's executor acknowledged.")(run)
    run = click.option("--robot", default=None, help="Only this robot (its coral.dev/robot label).")(run)
    return system_target(halt_control.HaltError)(run)


def _wait(
    control: halt_control.HaltControl, system: str, robot: str | None, halt: HaltSpec | None, wait_s: float
) -> None:
    """Waits until the operator passed `halt` on and every targeted robot's executor acknowledged it."""
    started = time.monotonic()
    pending: list[str] = []

    def done() -> bool:
        instances = control.instances(system, robot)
        pending[:] = sorted(
            str((i.get("spec") or {}).get("robot", "?"))
            for i in instances
            if not (halt_control.wanted_on(i, halt) and halt_control.acknowledged(i))
        )
        return bool(instances) and not pending

    if not polling.poll_until(done, timeout_s=wait_s, interval_s=0.2):
        waiting = ", ".join(pending) or "robots of the system (none found)"
        raise click.ClickException(f"not acknowledged within {wait_s:g} s by {waiting}")
    click.echo(f"acknowledged by every robot in {time.monotonic() - started:.1f} s")


@click.command("halt")
@_target
@click.option(
    "--park-tree", default=None, help="ID of a BehaviorTree each robot ticks to its end before halting."
)
@click.option(
    "--park-timeout",
    type=click.IntRange(1, MAX_PARK_SECONDS),
    default=30,
    show_default=True,
    help="Seconds the park tree may run.",
)
def halt_command(
    system: str,
    robot: str | None,
    namespace: str,
    wait: bool,
    timeout_s: float,
    park_tree: str | None,
    park_timeout: int,
) -> None:
    """Halt the trees of a system's robots (an operational stop, not a safety stop).

    Each executor halts its tree as BT.CPP's haltTree() does, after ticking --park-tree to its end
    if given, and ticks it no more until `coral resume`. No pod restarts; drivers and skillsets
    keep running. Sets spec.halt, as a GitOps change can.
    """
    control = halt_control.HaltControl.from_kubeconfig(namespace)
    new = control.change(system, lambda current: halt_control.halted(current, robot, park_tree, park_timeout))
    click.echo(
        f"coralsystem/{system} halted: {', '.join(new.robots) if new and new.robots else 'every robot'}"
    )
    if wait:
        _wait(control, system, robot, new, timeout_s)


@click.command("resume")
@_target
def resume_command(system: str, robot: str | None, namespace: str, wait: bool, timeout_s: float) -> None:
    """Let halted trees run again, each from its start (clears spec.halt, or the robot from it)."""
    control = halt_control.HaltControl.from_kubeconfig(namespace)
    new = control.change(system, lambda current: halt_control.resumed(current, robot, system))
    still = f" ({', '.join(new.robots)} still halted)" if new is not None else ""
    click.echo(f"coralsystem/{system} resumed: {robot or 'every robot'}{still}")
    if wait:
        _wait(control, system, robot, new, timeout_s)
