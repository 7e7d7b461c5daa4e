"""What every command that steers one CoralSystem shares: its SYSTEM argument and --namespace, and
its own errors ending it with their message instead of a traceback."""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

import click


def system_target(error: type[Exception]) -> Callable[[Callable[..., None]], Callable[..., None]]:
    """Decorator: SYSTEM and -n/--namespace; `error` becomes a clean CLI error (exit 1)."""

    def decorate(function: Callable[..., None]) -> Callable[..., None]:
        @functools.wraps(function)
        def run(*args: Any, **kwargs: Any) -> None:
            try:
                function(*args, **kwargs)
            except error as raised:
                raise click.ClickException(str(raised)) from raised

        run = click.option("-n", "--namespace", default="default", show_default=True)(run)
        return click.argument("system")(run)

    return decorate
