"""The terminal side of `coral run`: prefixed, coloured component logs and the live tree view.

On a terminal the tree view is a footer redrawn below the scrolling logs; elsewhere (pipes, CI,
tests) it degrades to one plain progress line whenever the root status or active node changes,
at most every `progress_interval_s`. `TreeView` folds the executor's status records (JSON lines,
`transition` and `status` events) into what is displayed. Called by `coral.local.supervising`.
"""

from __future__ import annotations

import json
import shutil
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TextIO

COLOURS = [36, 33, 35, 32, 34, 91, 96, 93]
STATUS_COLOUR = {"RUNNING": 33, "SUCCESS": 32, "FAILURE": 31, "IDLE": 90, "SKIPPED": 90, "HALTED": 90}
MAX_VIEW_LINES = 18


GENERIC_TAGS = ("Action", "Condition", "Control", "Decorator")


def outline_of(tree_file: Path, main_tree: str | None = None) -> dict[int, tuple[int, str]]:
    """uid -> (depth, node ID) of the main tree, numbered depth-first from 1 with subtrees expanded,
    as the engine numbers node paths (`Name::uid`); empty when the file cannot be read."""
    import xml.etree.ElementTree as ElementTree

    try:
        root = ElementTree.parse(tree_file).getroot()
    except (OSError, ElementTree.ParseError):
        return {}
    trees = {tree.get("ID"): tree for tree in root.findall("BehaviorTree")}
    main = main_tree or root.get("main_tree_to_execute") or next(iter(trees), None)
    if main not in trees:
        return {}
    outline: dict[int, tuple[int, str]] = {}

    def visit(element: Any, depth: int, open_trees: frozenset[str]) -> None:
        node_id = element.get("ID") if element.tag in GENERIC_TAGS else element.tag
        outline[len(outline) + 1] = (depth, str(node_id))
        children = list(element)
        if element.tag == "SubTree":
            target = element.get("ID")
            children = list(trees[target]) if target in trees and target not in open_trees else []
            open_trees = open_trees | {str(target)}
        for child in children:
            visit(child, depth + 1, open_trees)

    for child in trees[main]:
        visit(child, 0, frozenset({str(main)}))
    return outline


def _uid(path: str) -> int | None:
    tail = path.rsplit("/", 1)[-1]
    number = tail.rsplit("::", 1)[-1] if "::" in tail else ""
    return int(number) if number.isdigit() else None


@dataclass
class TreeView:
    """Latest status of every node seen in transitions, in first-seen (tree) order."""

    nodes: dict[str, tuple[str, str]] = field(default_factory=dict)  # path -> (node_id, status)
    results: dict[str, str] = field(default_factory=dict)  # path -> last SUCCESS/FAILURE/SKIPPED
    root: str = "IDLE"
    ticks: int = 0
    active: str = ""
    finished: dict[str, Any] | None = None
    waiting: list[str] = field(default_factory=list)
    errors: list[str] = field(default_factory=list)
    outline: dict[int, tuple[int, str]] = field(default_factory=dict)

    def apply(self, record: dict[str, Any]) -> None:
        event = record.get("event")
        if event == "transition":
            path, status = str(record.get("path")), str(record.get("status"))
            self.nodes[path] = (str(record.get("node_id")), status)
            if status in ("SUCCESS", "FAILURE", "SKIPPED"):
                self.results[path] = status
        elif event == "status":
            self.root = str(record.get("root", self.root))
            self.ticks = int(record.get("tick_count", self.ticks) or 0)
            self.active = str(record.get("active_path", "") or "")
            self.waiting = []
        elif event == "waiting":
            self.waiting = list(record.get("missing", []))
        elif event == "error":
            self.errors.append(str(record.get("message")))
        elif event == "finished":
            self.finished = record
            self.root = str(record.get("root", self.root))
            self.ticks = int(record.get("tick_count", self.ticks) or self.ticks)

    def lines(self, colour: bool, max_lines: int = MAX_VIEW_LINES) -> list[str]:
        def paint(text: str, code: int) -> str:
            return f"\x1b[{code}m{text}\x1b[0m" if colour else text

        head = f"tree {paint(self.root, STATUS_COLOUR.get(self.root, 0))}  ticks {self.ticks}"
        if self.waiting:
            head += f"  waiting for node types: {', '.join(self.waiting)}"
        out = [head]
        base = min((p.count("/") for p in self.nodes), default=0)

        def order(path: str) -> int:
            uid = _uid(path)
            return uid if uid is not None else 1 << 30

        # Tree order when paths carry uids; the outline gives true depths when it matches the tree.
        paths = sorted(self.nodes, key=order)
        for path in paths[: max(1, max_lines - 1)]:
            node_id, status = self.nodes[path]
            known = self.outline.get(order(path))
            depth = known[0] if known and known[1] == node_id else path.count("/") - base
            marker = "▶" if path == self.active else " "
            shown = paint(status, STATUS_COLOUR.get(status, 0))
            if status == "IDLE" and path in self.results:
                # An idle node shows what it last returned, dimmed, as Groot2 does.
                shown = paint(f"({self.results[path].lower()})", 90)
            label = node_id
            if node_id == "SubTree":
                label = f"SubTree {path.rsplit('/', 1)[-1].split('::')[0]}"
            out.append(f"{marker} {'  ' * depth}{label:<28} {shown}")
        return out

    def progress_line(self) -> str:
        text = f"tree {self.root} ticks={self.ticks}"
        if self.active:
            text += f" active={self.active}"
        if self.waiting:
            text += f" waiting for {', '.join(self.waiting)}"
        return text


class StatusTail:
    """Reads new JSON lines appended to a status file, tolerating a partially written last line."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.offset = 0
        self.partial = ""

    def read(self) -> list[dict[str, Any]]:
        try:
            with self.path.open("r", encoding="utf-8") as handle:
                handle.seek(self.offset)
                chunk = handle.read()
                self.offset = handle.tell()
        except FileNotFoundError:
            return []
        text = self.partial + chunk
        lines = text.split("\n")
        self.partial = lines.pop()
        records = []
        for line in lines:
            try:
                records.append(json.loads(line))
            except ValueError:
                continue
        return records


class Console:
    """Serialises log lines and the tree footer onto one stream."""

    def __init__(
        self,
        stream: TextIO | None = None,
        *,
        live: bool | None = None,
        colour: bool | None = None,
        progress_interval_s: float = 2.0,
    ) -> None:
        self.stream = stream or sys.stdout
        tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.live = tty if live is None else live
        self.colour = tty if colour is None else colour
        self.progress_interval_s = progress_interval_s
        self._lock = threading.Lock()
        self._footer: list[str] = []
        self._colours: dict[str, int] = {}
        self._width = 0
        self._last_progress = ("", 0.0)

    def register(self, name: str) -> None:
        self._colours.setdefault(name, COLOURS[len(self._colours) % len(COLOURS)])
        self._width = max(self._width, len(name))

    def _clear_footer(self) -> None:
        if self.live and self._footer:
            self.stream.write(f"\x1b[{len(self._footer)}F\x1b[J")

    def _draw_footer(self) -> None:
        if self.live and self._footer:
            self.stream.write("\n".join(self._footer) + "\n")

    def log(self, name: str, line: str) -> None:
        prefix = f"{name:<{self._width}} | "
        if self.colour:
            prefix = f"\x1b[{self._colours.get(name, 0)}m{prefix}\x1b[0m"
        with self._lock:
            self._clear_footer()
            self.stream.write(prefix + line.rstrip("\n") + "\n")
            self._draw_footer()
            self.stream.flush()

    def note(self, text: str) -> None:
        self.log("coral", text)

    def show(self, view: TreeView) -> None:
        if self.live:
            with self._lock:
                self._clear_footer()
                rows = shutil.get_terminal_size((100, 40)).lines
                self._footer = view.lines(self.colour, max_lines=max(8, rows - 6))
                self._draw_footer()
                self.stream.flush()
            return
        line = view.progress_line()
        now = time.monotonic()
        previous, at = self._last_progress
        root_changed = line.split(" ", 2)[:2] != previous.split(" ", 2)[:2]
        if line != previous and (root_changed or now - at >= self.progress_interval_s):
            self._last_progress = (line, now)
            self.note(line)

    def close_footer(self) -> None:
        with self._lock:
            self._footer = []
