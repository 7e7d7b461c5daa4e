"""`coral logs TARGET`: one verb for the logs of a run on this machine and of a fleet in a cluster.

The local runtime (`coral run`'s runs, by handle) and the operator's user verbs (a CoralSystem's
pods, through the API server) each register how they read logs as an entry point of the group
`coral.logs` (setup.py). Neither side may import the other, so this verb, which both can reach,
asks them in turn: the local runtime takes TARGET when it is the handle of a run here, and the
cluster takes anything else. A copy that has only one side (a component image, the operator's
image) offers only that side's form.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from importlib import metadata

import click

LOGS_GROUP = "coral.logs"


@dataclass(frozen=True)
class LogsSource:
    """How one side of the project reads logs, registered in `LOGS_GROUP`."""

    command: click.Command
    claims: Callable[[Sequence[str]], bool] | None
    """Whether the arguments name something of this side (cheap, local checks only); None for the
    side that takes whatever the others did not claim."""


def installed_sources() -> list[LogsSource]:
    """Every installed side's source, the one that takes the rest last."""
    sources = [
        entry.load() for entry in sorted(metadata.entry_points(group=LOGS_GROUP), key=lambda e: e.name)
    ]
    return sorted(sources, key=lambda source: source.claims is None)


def choose_source(sources: Sequence[LogsSource], args: Sequence[str]) -> LogsSource | None:
    """The first source that claims `args`, else the one that takes the rest, else the last one (it
    then says why TARGET is not its own)."""
    for source in sources:
        if source.claims is None or source.claims(args):
            return source
    return sources[-1] if sources else None


class LogsVerb(click.Command):
    """Hands its arguments, unparsed, to the command of the source that claims them."""

    def __init__(self) -> None:
        super().__init__(
            "logs",
            help="Print the logs of a local run (by handle) or of a CoralSystem's robots.",
            params=[click.Argument(["args"], nargs=-1, type=click.UNPROCESSED)],
            context_settings={"ignore_unknown_options": True, "allow_interspersed_args": False},
            add_help_option=False,
        )

    def invoke(self, ctx: click.Context) -> None:
        args: list[str] = list(ctx.params["args"])
        sources = installed_sources()
        if not args or args[0] in ("-h", "--help"):
            click.echo(self._help(ctx, sources), color=ctx.color)
            return
        source = choose_source(sources, args)
        if source is None:
            raise click.ClickException("no part of Coral that reads logs is installed")
        with source.command.make_context(ctx.info_name, args, parent=ctx.parent) as chosen:
            source.command.invoke(chosen)

    def _help(self, ctx: click.Context, sources: Sequence[LogsSource]) -> str:
        parts = [
            "TARGET is the handle of a run on this machine (`coral ps`) or, when no run has it, the "
            "name of a CoralSystem in the cluster.",
        ]
        for source in sources:
            with source.command.make_context(
                ctx.info_name, [], resilient_parsing=True, parent=ctx.parent
            ) as sub:
                parts.append(source.command.get_help(sub))
        return "\n\n".join(parts)


logs_command = LogsVerb()
