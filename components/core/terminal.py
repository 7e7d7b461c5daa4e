"""What every `coral` verb shows on a terminal: one rich Console factory, status colours, tables.

On a terminal output is coloured and may redraw (live views); anywhere else (pipes, files, CI logs)
the same calls write plain text with no ANSI codes and no wrapping, so logs stay readable and
greppable. Used by `coral run` (`coral.local.console`), `coral ps`, `coral dev-cluster local status` and
the mission follower of `coral demo`.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import contextmanager
from typing import TextIO

from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)
from rich.table import Table
from rich.text import Text

# Groot2's colours for node statuses; IDLE/SKIPPED/HALTED are dimmed.
STATUS_STYLE = {
    "RUNNING": "yellow",
    "SUCCESS": "green",
    "FAILURE": "red",
    "IDLE": "bright_black",
    "SKIPPED": "bright_black",
    "HALTED": "bright_black",
}
# Off a terminal nothing wraps: a line of a CI log stays one line.
PLAIN_WIDTH = 10_000


def console(stream: TextIO | None = None, *, colour: bool | None = None) -> Console:
    """A rich Console on `stream` (default stdout): styled on a terminal, plain text elsewhere.

    `colour` forces styling on or off; by default it follows whether `stream` is a terminal
    (and rich's own NO_COLOR / FORCE_COLOR / TERM=dumb rules).
    """
    stream = stream or sys.stdout
    tty = bool(getattr(stream, "isatty", lambda: False)())
    return Console(
        file=stream,
        force_terminal=colour,
        no_color=True if colour is False else None,
        width=None if tty else PLAIN_WIDTH,
        highlight=False,
        markup=False,
        emoji=False,
    )


def status_text(status: str) -> Text:
    return Text(status, style=STATUS_STYLE.get(status, ""))


@contextmanager
def progress(description: str, stream: TextIO | None = None) -> Iterator[Callable[[int, int], None]]:
    """A progress bar for a long step, fed `(done, total)`; off a terminal it shows nothing, as the
    step's own start and end lines say enough in a log."""
    out = console(stream)
    if not out.is_terminal:
        yield lambda done, total: None
        return
    columns = (
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        TextColumn("eta"),
        TimeRemainingColumn(),
    )
    with Progress(*columns, console=out, transient=True) as bar:
        task = bar.add_task(description, total=None)
        yield lambda done, total: bar.update(task, completed=done, total=total)


def health_text(healthy: bool, alive: bool) -> Text:
    """`healthy` (green), `unhealthy` (alive but failing its probe, yellow) or `stopped` (red)."""
    if healthy:
        return Text("healthy", style="green")
    return Text("unhealthy", style="yellow") if alive else Text("stopped", style="red")


def table(
    columns: Sequence[str], rows: Iterable[Sequence[str | Text]], *, right: Sequence[str] = ()
) -> Table:
    """A borderless table with a bold header, as `kubectl get` prints (columns in `right` align right)."""
    grid = Table(box=None, pad_edge=False, show_edge=False, header_style="bold", padding=(0, 2, 0, 0))
    for name in columns:
        grid.add_column(name, justify="right" if name in right else "left", no_wrap=True)
    for row in rows:
        grid.add_row(*row)
    return grid
