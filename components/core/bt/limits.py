"""Bounds on what one tree document may cost to load, checked before the loader sees the text.

Whoever validates trees for someone else (the operator, for every namespace it serves) must not
let one document exhaust its memory or stack. `check_document` scans the text with expat in one
pass, keeping only counters (no recursion, no tree in memory), and refuses:

- a document larger than `max_bytes`;
- more than `max_elements` elements, or elements nested deeper than `max_depth`;
- DTD entity declarations: BT.CPP's parser (tinyxml2) never expands them, and expanding them is
  how a few hundred bytes become gigabytes ("billion laughs").

`IncludeBudget` carries the totals over a document and everything it includes. Every refusal
names the file and line and gives the figure and the limit.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from xml.parsers import expat

from coral_core.bt.errors import BTLoadError
from coral_core.bt.xml_lenient import sanitize


@dataclass(frozen=True)
class TreeLimits:
    """What one tree, with everything it includes, may cost to load."""

    max_bytes: int = 768 * 1024
    """UTF-8 size of all files together (an immutable ConfigMap holds at most 1 MiB)."""
    max_elements: int = 50_000
    """Elements of all files together."""
    max_depth: int = 128
    """Nesting of elements in one file (BT.CPP trees in the wild stay below 30)."""
    max_includes: int = 32
    """`<include>` elements followed, over all files."""


@dataclass
class IncludeBudget:
    """What the files loaded so far have used of the limits."""

    limits: TreeLimits = field(default_factory=TreeLimits)
    bytes: int = 0
    elements: int = 0
    includes: int = 0

    def count_include(self, filename: str, line: int) -> None:
        self.includes += 1
        if self.includes > self.limits.max_includes:
            raise BTLoadError(
                f"more than {self.limits.max_includes} <include>s; the limit is {self.limits.max_includes}",
                file=filename,
                line=line,
            )


class _Refused(Exception):
    def __init__(self, message: str, line: int) -> None:
        super().__init__(message)
        self.message = message
        self.line = line


def check_document(text: str, filename: str, budget: IncludeBudget) -> None:
    """Raise `BTLoadError` if `text` breaks a limit; add its size and elements to `budget`.

    Malformed XML is left to the loader, which reports it with its line; the scan stops there.
    """
    limits = budget.limits
    size = len(text.encode("utf-8", errors="replace"))
    if budget.bytes + size > limits.max_bytes:
        total = budget.bytes + size
        raise BTLoadError(
            f"the tree is {total} bytes with its includes; the limit is {limits.max_bytes}",
            file=filename,
            line=1,
        )
    budget.bytes += size
    parser = expat.ParserCreate()
    depth = 0
    deepest = 0
    elements_before = budget.elements
    # Lines of the first element past each limit; the scan goes on (the size is bounded already)
    # so the message can give the document's real figure.
    too_deep: int | None = None
    too_many: int | None = None

    def start(tag: str, attrs: dict[str, str]) -> None:
        nonlocal depth, deepest, too_deep, too_many
        depth += 1
        deepest = max(deepest, depth)
        budget.elements += 1
        if depth > limits.max_depth and too_deep is None:
            too_deep = parser.CurrentLineNumber
        if budget.elements > limits.max_elements and too_many is None:
            too_many = parser.CurrentLineNumber

    def end(tag: str) -> None:
        nonlocal depth
        depth -= 1

    def entity(name: str, *_: object) -> None:
        raise _Refused(
            f"entity declarations are not allowed (<!ENTITY {name}>); BT.CPP does not expand them",
            parser.CurrentLineNumber,
        )

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    parser.EntityDeclHandler = entity
    try:
        parser.Parse(sanitize(text), True)
    except _Refused as refused:
        raise BTLoadError(refused.message, file=filename, line=refused.line) from None
    except expat.ExpatError:
        pass
    if too_deep is not None:
        raise BTLoadError(
            f"elements nest {deepest} levels deep; the limit is {limits.max_depth}",
            file=filename,
            line=too_deep,
        )
    if too_many is not None:
        raise BTLoadError(
            f"the tree has {budget.elements} elements with its includes "
            f"({budget.elements - elements_before} in this file); the limit is {limits.max_elements}",
            file=filename,
            line=too_many,
        )
