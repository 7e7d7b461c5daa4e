"""Reading a Dockerfile just far enough to know which build-context files it uses and its ARGs.

Used by `fingerprints` (the COPY/ADD sources decide which context files count) and by `catalog`
checks (every build argument the catalog sets must be declared). Pure; errors name the file and line.
"""

from __future__ import annotations

import json
import shlex
from dataclasses import dataclass
from pathlib import Path


class DockerfileError(ValueError):
    """A Dockerfile this module cannot read; the message names the file and line."""


@dataclass(frozen=True)
class Instruction:
    keyword: str
    arguments: str
    line: int


@dataclass(frozen=True)
class Dockerfile:
    path: Path
    instructions: tuple[Instruction, ...]

    def args(self) -> dict[str, str | None]:
        """ARG names with their defaults (None when the ARG has none)."""
        found: dict[str, str | None] = {}
        for instruction in self.of("ARG"):
            for word in shlex.split(instruction.arguments):
                name, sep, default = word.partition("=")
                found[name] = default if sep else None
        return found

    def of(self, keyword: str) -> list[Instruction]:
        return [i for i in self.instructions if i.keyword == keyword]

    def context_sources(self) -> list[str] | None:
        """The context paths COPY and ADD read (globs as written), None if any depends on an ARG.

        `COPY --from=...` reads another stage or image, not the context, so it is left out.
        """
        sources: list[str] = []
        for instruction in self.of("COPY") + self.of("ADD"):
            words = self._words(instruction)
            flags = [w for w in words if w.startswith("--")]
            paths = [w for w in words if not w.startswith("--")]
            if any(f.startswith("--from=") for f in flags):
                continue
            if len(paths) < 2:
                raise DockerfileError(
                    f"{self.path}:{instruction.line}: {instruction.keyword} needs a source and a destination"
                )
            for source in paths[:-1]:
                if "$" in source:
                    return None
                sources.append(source)
        return sources

    def _words(self, instruction: Instruction) -> list[str]:
        text = instruction.arguments.strip()
        if text.startswith("["):
            try:
                words = json.loads(text)
            except json.JSONDecodeError as error:
                raise DockerfileError(
                    f"{self.path}:{instruction.line}: {instruction.keyword} JSON form is invalid: {error}"
                ) from error
            if not isinstance(words, list) or not all(isinstance(w, str) for w in words):
                raise DockerfileError(
                    f"{self.path}:{instruction.line}: {instruction.keyword} JSON form must list strings"
                )
            return words
        try:
            return shlex.split(text)
        except ValueError as error:
            raise DockerfileError(f"{self.path}:{instruction.line}: {error}") from error


def parse(text: str, path: Path) -> Dockerfile:
    """Splits `text` into instructions, joining `\\` continuations and dropping comments."""
    instructions: list[Instruction] = []
    pending: list[str] = []
    start = 0
    for number, raw in enumerate(text.splitlines(), start=1):
        stripped = raw.strip()
        if not pending and (not stripped or stripped.startswith("#")):
            continue
        if pending and stripped.startswith("#"):
            continue
        if not pending:
            start = number
        if stripped.endswith("\\"):
            pending.append(stripped[:-1])
            continue
        pending.append(stripped)
        joined = " ".join(part.strip() for part in pending if part.strip())
        pending = []
        keyword, _, arguments = joined.partition(" ")
        if not keyword.isalpha():
            raise DockerfileError(f"{path}:{start}: {keyword!r} is not a Dockerfile instruction")
        instructions.append(Instruction(keyword.upper(), arguments.strip(), start))
    if pending:
        raise DockerfileError(f"{path}:{start}: the last instruction ends in a line continuation")
    if not any(i.keyword == "FROM" for i in instructions):
        raise DockerfileError(f"{path}: no FROM instruction")
    return Dockerfile(path, tuple(instructions))


def read(path: Path) -> Dockerfile:
    try:
        text = path.read_text()
    except OSError as error:
        raise DockerfileError(f"{path}: cannot read: {error.strerror}") from error
    return parse(text, path)
