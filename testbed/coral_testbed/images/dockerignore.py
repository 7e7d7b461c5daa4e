""".dockerignore rules: which files of a build context the builder sends.

Used by `fingerprints` so an image's fingerprint covers exactly the files its build can see. Follows
the builders' rules: patterns are matched against the slash-separated path relative to the context
(`*` and `?` stay within one path element, `**` spans any number of them), a pattern that matches a
folder excludes everything under it, `!pattern` re-includes, and the last matching line wins.
"""

from __future__ import annotations

import posixpath
import re
from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class Rule:
    pattern: str
    regex: re.Pattern[str]
    include: bool


def _translate(pattern: str) -> re.Pattern[str]:
    out: list[str] = []
    i = 0
    while i < len(pattern):
        char = pattern[i]
        if pattern.startswith("**", i):
            # `**/` matches zero or more whole folders; a trailing `**` matches everything below.
            if pattern.startswith("**/", i):
                out.append("(?:.*/)?")
                i += 3
            else:
                out.append(".*")
                i += 2
            continue
        if char == "*":
            out.append("[^/]*")
        elif char == "?":
            out.append("[^/]")
        elif char == "[":
            end = pattern.find("]", i + 1)
            if end == -1:
                out.append(re.escape(char))
            else:
                body = pattern[i + 1 : end]
                if body.startswith("^") or body.startswith("!"):
                    body = "^" + body[1:]
                out.append(f"[{body}]")
                i = end
        elif char == "\\" and i + 1 < len(pattern):
            i += 1
            out.append(re.escape(pattern[i]))
        else:
            out.append(re.escape(char))
        i += 1
    return re.compile("".join(out) + r"\Z")


def parse(text: str) -> list[Rule]:
    """The rules of a .dockerignore file, in order; blank lines and `#` comments are skipped."""
    rules = []
    for raw in text.splitlines():
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        include = line.startswith("!")
        if include:
            line = line[1:].strip()
        cleaned = posixpath.normpath(line).lstrip("/")
        if cleaned in ("", "."):
            continue
        rules.append(Rule(pattern=cleaned, regex=_translate(cleaned), include=include))
    return rules


def read(context: Path) -> list[Rule]:
    """The rules of `context`/.dockerignore (or .containerignore, which builders read first)."""
    for name in (".containerignore", ".dockerignore"):
        path = context / name
        if path.is_file():
            return parse(path.read_text())
    return []


def _matches(rule: Rule, path: str) -> bool:
    # A pattern naming a folder also covers everything inside it.
    parts = path.split("/")
    return any(rule.regex.match("/".join(parts[:n])) for n in range(1, len(parts) + 1))


def is_excluded(rules: list[Rule], path: str) -> bool:
    """Whether the context-relative `path` (slash-separated) is left out of the build context."""
    excluded = False
    for rule in rules:
        if _matches(rule, path):
            excluded = not rule.include
    return excluded


def can_prune(rules: list[Rule], folder: str) -> bool:
    """Whether a walk may skip `folder` whole: excluded, and no `!` rule could bring back a file."""
    return is_excluded(rules, folder) and not any(rule.include for rule in rules)
