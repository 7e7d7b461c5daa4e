"""Error types of the engine: load/validation errors carry file:line, runtime errors the node path."""

from __future__ import annotations


class BTError(Exception):
    """Base error; str() reads "file:line: message" or "node path: message"."""

    def __init__(
        self, message: str, *, file: str | None = None, line: int | None = None, node_path: str | None = None
    ) -> None:
        self.message = message
        self.file = file
        self.line = line
        self.node_path = node_path
        super().__init__(self._render())

    def _render(self) -> str:
        if self.file is not None:
            where = f"{self.file}:{self.line}" if self.line else self.file
            if self.node_path:
                where += f": {self.node_path}"
            return f"{where}: {self.message}"
        if self.node_path:
            return f"{self.node_path}: {self.message}"
        return self.message

    def __str__(self) -> str:
        return self._render()


class BTLoadError(BTError):
    """Raised while parsing, building or statically validating a tree."""


class BTRuntimeError(BTError):
    """Raised while ticking; node_path names the node whose tick failed."""


class ScriptError(BTError):
    """Syntax or evaluation error of the scripting language (wrapped by callers with a location)."""
