"""`coral rollout status|pause|resume|undo`: watch and steer a CoralSystem's fleet rollout.

Thin verbs over `rollout_control`, which reads `status.rollout` and writes what the operator
reads: `spec.rollout.paused` (pause, resume), the removal of a recorded health-gate failure
(resume) and the `coral.dev/rollout-undo` annotation (undo). Loaded lazily by `coral_core.command`.
"""

from __future__ import annotations

import json

import click
from coral_core import polling, terminal
from rich.console import Group, RenderableType
from rich.padding import Padding
from rich.text import Text

from coral_operator import rollout_control
from coral_operator.api import keys
from coral_operator.system_cli import system_target

TONE_STYLE = {"ok": "green", "warn": "yellow", "bad": "red", "": ""}
"""How a terminal colours the tone of a line of `rollout_control.Report`."""

_target = system_target(rollout_control.RolloutError)


def _view(said: rollout_control.Report) -> Group:
    """The report as rich draws it: the counts as a table, what went wrong in colour; plain text
    with the same words in a pipe."""
    parts: list[RenderableType] = [Text(said.title, style="bold")]
    if said.spec:
        headers = [header for _key, header in rollout_control.COUNT_COLUMNS]
        row = [str(said.counts[key]) for key, _header in rollout_control.COUNT_COLUMNS]
        parts += [
            Text(f"  {said.spec}"),
            Padding(terminal.table(headers, [row], right=headers), (0, 0, 0, 2), expand=False),
        ]
    parts += [Text(f"  {text}", style=TONE_STYLE[tone]) for text, tone in [*said.notes, said.verdict]]
    return Group(*parts)


@click.group()
def rollout() -> None:
    """Watch and steer the rollout of a CoralSystem over its robots."""


@rollout.command("status")
@_target
@click.option(
    "-w", "--watch", is_flag=True, help="Print again on every change until the rollout completes or fails."
)
@click.option("--timeout", default=600.0, show_default=True, help="Seconds to watch at most.")
@click.option("-o", "--output", type=click.Choice(["text", "json"]), default="text", show_default=True)
def status_command(system: str, namespace: str, watch: bool, timeout: float, output: str) -> None:
    """Show where the rollout stands: target and current revision, counts, what it waits for.

    Exits 1 when the health gate failed, when the fleet was rolled back (robots do not run the
    spec's revision), when the system is Stalled (a refused spec, a robot whose component or tree
    failed), or when --watch gives up after --timeout; a status written for an older generation
    of the spec never counts as complete.
    """
    control = rollout_control.RolloutControl.from_kubeconfig(namespace)
    out = terminal.console()
    shown: list[str] = []
    waiting_for: list[str] = []

    def settled() -> bool:
        """Shows the rollout if it changed; True once it completed (or at once without --watch)."""
        body = control.read(system)
        if output == "json":
            text = json.dumps((body.get("status") or {}).get(keys.SYSTEM_STATUS.rollout) or {}, indent=2)
            if shown[-1:] != [text]:
                click.echo(text)
        else:
            text = rollout_control.describe(body)
            if shown[-1:] != [text]:
                out.print(_view(rollout_control.report(body)))
        shown[:] = [text]
        progress = rollout_control.evaluate_progress(body)
        if progress.failure is not None:
            raise click.ClickException(f"the rollout of {system} failed: {progress.failure}")
        waiting_for[:] = [progress.waiting_for]
        return progress.done or not watch

    if not polling.poll_until(settled, timeout_s=timeout, interval_s=1.0):
        raise click.ClickException(
            f"the rollout of {system} did not complete within {timeout:g} s (waiting for {waiting_for[0]})"
        )


@rollout.command("pause")
@_target
def pause_command(system: str, namespace: str) -> None:
    """Stop moving robots to the new revision (sets spec.rollout.paused)."""
    rollout_control.RolloutControl.from_kubeconfig(namespace).pause(system)
    click.echo(f"coralsystem/{system} rollout paused")


@rollout.command("resume")
@_target
def resume_command(system: str, namespace: str) -> None:
    """Resume a paused rollout, also after a health-gate failure paused it."""
    rollout_control.RolloutControl.from_kubeconfig(namespace).resume(system)
    click.echo(f"coralsystem/{system} rollout resumed")


@rollout.command("undo")
@_target
def undo_command(system: str, namespace: str) -> None:
    """Return every robot to the previous revision (until the spec changes again)."""
    revision = rollout_control.RolloutControl.from_kubeconfig(namespace).undo(system)
    click.echo(f"coralsystem/{system} rolling back from revision {revision}")
