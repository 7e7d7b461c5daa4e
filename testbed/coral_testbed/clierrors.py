"""One way for the testbed's click commands to turn their own errors into a clean CLI message."""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

import click


def fail_on(*errors: type[BaseException]) -> Callable[[Callable[..., Any]], Callable[..., Any]]:
    """Decorator: the listed errors end the command with their message (exit 1), not a traceback."""

    def decorate(command: Callable[..., Any]) -> Callable[..., Any]:
        @functools.wraps(command)
        def wrapper(*args: Any, **kwargs: Any) -> Any:
            try:
                return command(*args, **kwargs)
            except errors as error:
                raise click.ClickException(str(error)) from error

        return wrapper

    return decorate
