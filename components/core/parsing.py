"""Parsing text that comes from outside the process: the files a user writes (compose, `.env`,
parameters, trees, manifests) and the JSON other processes send (heartbeats, plugin manifests,
messages between robots). A file that is not UTF-8 text, or a document nested deeper than the
parser's recursion can follow, is an error like any other mistake in it, never a traceback or a
crashed thread.

A stray Latin-1 byte (a `°` typed in an editor set to another encoding) or a truncated binary
copied over a YAML file are mistakes a robotics team makes; PyYAML's composer and the json module
recurse once per nesting level, so a few thousand unclosed `[` exhaust Python's stack.

YAML written by someone else (a CoralSystem's parameters) is first measured by `check_yaml`, on the
parser's event stream, before any node or object is built: aliases and merge keys (`<<`) let a few
hundred bytes stand for millions of entries, which PyYAML's constructor copies out (issue 47).
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
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


class OverLimit(yaml.MarkedYAMLError):
    """A YAML document past one of its `YamlLimits`; `problem` names the figure and the limit."""

    def __init__(self, problem: str, mark: yaml.Mark | None) -> None:
        super().__init__(problem=problem, problem_mark=mark)


@dataclass(frozen=True)
class YamlLimits:
    """What one YAML stream may expand to. An entry is a node (scalar, sequence, mapping) of the
    document as built, aliases and merge keys expanded: what a reader that copies it (a JSON dump,
    rcl's parser, PyYAML's merge) holds."""

    max_entries: int = 100_000
    max_aliases: int = 1_000
    max_merge_keys: int = 1_000
    max_depth: int = 64


PARAMETER_LIMITS = YamlLimits()
"""The bounds of a ROS parameters file, on the operator and on the robot alike."""

# The tags the safe constructor builds; any other is refused before construction, as it would be.
_SAFE_TAGS = frozenset(tag for tag in yaml.SafeLoader.yaml_constructors if tag is not None) | {"!"}
_EVENT_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


@dataclass
class _Tally:
    limits: YamlLimits
    entries: int = 0
    aliases: int = 0
    merge_keys: int = 0
    over: tuple[str, yaml.Mark | None] | None = None

    def count(self, field: str, added: int, mark: yaml.Mark | None) -> None:
        value = getattr(self, field) + added
        setattr(self, field, value)
        limit = getattr(self.limits, f"max_{field}")
        if value > limit and self.over is None:
            self.over = (field, mark)

    def problem(self) -> str | None:
        if self.over is None:
            return None
        field, _ = self.over
        words = {
            "entries": "expands to {} entries",
            "aliases": "has {} aliases",
            "merge_keys": "has {} merge keys (<<)",
        }
        figure = words[field].format(f"{getattr(self, field):,}")
        return f"{figure}; the limit is {getattr(self.limits, f'max_{field}'):,}"


def check_yaml(text: str, limits: YamlLimits = PARAMETER_LIMITS) -> str | None:
    """Measures a YAML stream against `limits` without building it; returns the kind of the first
    document's root (`mapping`, `sequence`, `scalar`, or None when there is none).

    Linear in the text and in memory bounded by its anchors and nesting: each alias counts as the
    entries of its anchor (known when the anchor closes), so the figure in a refusal is the whole
    expansion however large. Tags the safe loader would refuse are refused here too.

    Raises:
        OverLimit: past a limit; the problem names the figure and the limit, the mark the line
            where the limit was crossed.
        NestedTooDeep: nested deeper than `limits.max_depth`.
        yaml.YAMLError: not YAML.
    """
    tally = _Tally(limits)
    anchors: dict[str, int] = {}
    # One frame per open collection: [anchor, entries before it, children so far, is a mapping].
    stack: list[list[Any]] = []
    root: str | None = None
    documents = 0
    for event in yaml.parse(text, Loader=_EVENT_LOADER):
        mark = event.start_mark
        if isinstance(event, yaml.DocumentStartEvent):
            anchors.clear()
            documents += 1
            continue
        if not isinstance(event, yaml.NodeEvent | yaml.CollectionEndEvent):
            continue
        if isinstance(event, yaml.CollectionEndEvent):
            anchor, opened, _, _ = stack.pop()
            if anchor is not None:
                anchors[anchor] = tally.entries - opened
            continue
        tag = getattr(event, "tag", None)
        if tag is not None and tag not in _SAFE_TAGS:
            raise yaml.constructor.ConstructorError(
                None, None, f"could not determine a constructor for the tag {tag!r}", mark
            )
        parent = stack[-1] if stack else None
        if parent is not None:
            parent[2] += 1
            # Keys sit at odd positions of a mapping; `<<` merges the mapping(s) after it.
            if (
                parent[3]
                and parent[2] % 2 == 1
                and isinstance(event, yaml.ScalarEvent)
                and _is_merge_key(event)
            ):
                tally.count("merge_keys", 1, mark)
        if documents == 1 and root is None:
            root = (
                "mapping"
                if isinstance(event, yaml.MappingStartEvent)
                else "sequence"
                if isinstance(event, yaml.SequenceStartEvent)
                else "scalar"
            )
        if isinstance(event, yaml.AliasEvent):
            tally.count("aliases", 1, mark)
            if event.anchor in anchors:
                tally.count("entries", anchors[event.anchor], mark)
            elif any(frame[0] == event.anchor for frame in stack):
                raise OverLimit(f"the alias *{event.anchor} refers to a node that contains it", mark)
            else:
                # As PyYAML's composer words it.
                raise yaml.composer.ComposerError(None, None, f"found undefined alias {event.anchor!r}", mark)
        elif isinstance(event, yaml.ScalarEvent):
            tally.count("entries", 1, mark)
            if event.anchor is not None:
                anchors[event.anchor] = 1
        else:
            tally.count("entries", 1, mark)
            if len(stack) >= limits.max_depth:
                raise NestedTooDeep()
            stack.append([event.anchor, tally.entries - 1, 0, isinstance(event, yaml.MappingStartEvent)])
    problem = tally.problem()
    if problem is not None:
        raise OverLimit(problem, tally.over[1] if tally.over else None)
    return root


def _is_merge_key(event: yaml.ScalarEvent) -> bool:
    return event.value == "<<" and event.tag is None and bool(event.implicit[0])


def load_bounded_yaml(text: str, limits: YamlLimits = PARAMETER_LIMITS) -> Any:
    """`load_yaml` of a document first measured by `check_yaml` (which raises what it raises)."""
    check_yaml(text, limits)
    return load_yaml(text)


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
