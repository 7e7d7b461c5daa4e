"""What the testbed's click verbs share besides errors: their progress line and KEY=VALUE options.

Used by `coral dev-cluster` and `coral dev-cluster`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import click


def say(line: str) -> None:
    """One progress line on stderr (stdout carries what scripts read, such as a kubeconfig path)."""
    click.echo(f"==> {line}", err=True)


def parse_labels(ctx: click.Context, param: click.Parameter, values: tuple[str, ...]) -> dict[str, str]:
    labels = {}
    for value in values:
        key, sep, label_value = value.partition("=")
        if not sep or not key:
            raise click.BadParameter(f"{value!r} is not KEY=VALUE", ctx=ctx, param=param)
        labels[key] = label_value
    return labels


def labels_option(help: str) -> Callable[[Callable[..., Any]], Callable[..., Any]]:
    """`--label KEY=VALUE` (repeatable), passed to the verb as the dict `labels`."""
    return click.option("--label", "labels", multiple=True, callback=parse_labels, help=help)
