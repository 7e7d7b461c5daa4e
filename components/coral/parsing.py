"""Parsing text that comes from outside the process: the files a user writes (compose, `.env`,
parameters, trees, manifests) and the JSON other processes send (heartbeats, plugin manifests,
messages between robots). A file that is not UTF-8 text, or a document nested deeper than the
parser's recursion can follow, is an error like any other mistake in it, never a traceback or a
crashed thread.

A stray Latin-1 byte (a `°` typed in an editor set to another encoding) or a truncated binary
copied over a YAML file are mistakes a robotics team makes; PyYAML's composer and the json module
recurse once per nesting level, so a few thousand unclosed `[` exhaust Python's stack.
"""

from __future__ import annotations

import json
import os
from typing import Any

import yaml


class NotText(ValueError):
    """The file is not UTF-8 text; `reason` says which byte, `line` where."""

    def __init__(self, reason: str, line: int) -> None:
        super().__init__(f"line {line}: {reason}")
        self.reason = reason
        self.line = line


class NestedTooDeep(yaml.YAMLError):
    """A YAML document whose nesting the parser cannot follow."""

    problem = "the document nests too deeply to be read"

    def __init__(self) -> None:
        super().__init__(self.problem)


def read_text(path: str | os.PathLike[str]) -> str:
    """The file's text; raises `NotText` when it is not UTF-8 (and `OSError` when it cannot be read,
    which each caller words for its kind of file)."""
    with open(path, "rb") as handle:
        return decode(handle.read())


def decode(data: bytes) -> str:
    """`data` as UTF-8 text; raises `NotText` naming the first byte that is not, and its line."""
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as err:
        line = data.count(b"\n", 0, err.start) + 1
        raise NotText(f"not UTF-8 text (byte 0x{data[err.start]:02x})", line) from None


def compose_yaml(text: str) -> yaml.Node | None:
    """`yaml.compose`, with too deep a nesting raised as `NestedTooDeep` (a `yaml.YAMLError`)."""
    try:
        return yaml.compose(text)
    except RecursionError:
        raise NestedTooDeep() from None


def load_yaml(text: str) -> Any:
    """`yaml.safe_load`, with too deep a nesting raised as `NestedTooDeep` (a `yaml.YAMLError`)."""
    try:
        return yaml.safe_load(text)
    except RecursionError:
        raise NestedTooDeep() from None


def load_all_yaml(text: str) -> list[Any]:
    """`yaml.safe_load_all` as a list, with too deep a nesting raised as `NestedTooDeep`."""
    try:
        return list(yaml.safe_load_all(text))
    except RecursionError:
        raise NestedTooDeep() from None


def load_json(text: str | bytes) -> Any:
    """`json.loads`, with too deep a nesting raised as a `ValueError` (as malformed JSON is)."""
    try:
        return json.loads(text)
    except RecursionError:
        raise ValueError("the JSON nests too deeply to be read") from None
