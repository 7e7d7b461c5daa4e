"""The terminal side of `coral run`: prefixed, coloured component logs and the live tree view.

Drawn with rich: on a terminal the tree view is a live footer redrawn below the scrolling logs;
elsewhere (pipes, CI, tests) it degrades to one plain progress line whenever the root status or
active node changes, at most every `progress_interval_s`, and no line carries ANSI codes.
`TreeView` folds the executor's status records (JSON lines, `transition` and `status` events)
into what is displayed. Called by `coral.local.supervising`.
"""

from __future__ import annotations

import json
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TextIO

from coral_core import terminal
from rich.console import Group
from rich.live import Live
from rich.table import Table
from rich.text import Text

PREFIX_STYLES = ["cyan", "yellow", "magenta", "green", "blue", "bright_red", "bright_cyan", "bright_yellow"]
MAX_VIEW_LINES = 18
LABEL_WIDTH = 28


GENERIC_TAGS = ("Action", "Condition", "Control", "Decorator")


@dataclass(frozen=True)
class OutlineNode:
    depth: int
    node_id: str
    label: str
    """What a person reads: `SubTree IterateSLAM` for a subtree, the node's name when it has one."""


def outline_of(tree_file: Path, main_tree: str | None = None) -> dict[int, OutlineNode]:
    """uid -> node of the main tree, numbered depth-first from 1 with subtrees expanded, as the
    engine numbers node paths (`Name::uid`); empty when the file cannot be read."""
    import xml.etree.ElementTree as ElementTree

    try:
        root = ElementTree.parse(tree_file).getroot()
    except (OSError, ElementTree.ParseError):
        return {}
    trees = {tree.get("ID"): tree for tree in root.findall("BehaviorTree")}
    main = main_tree or root.get("main_tree_to_execute") or next(iter(trees), None)
    if main not in trees:
        return {}
    outline: dict[int, OutlineNode] = {}

    def visit(element: Any, depth: int, open_trees: frozenset[str]) -> None:
        node_id = str(element.get("ID") if element.tag in GENERIC_TAGS else element.tag)
        name = element.get("name")
        label = f"SubTree {element.get('ID')}" if element.tag == "SubTree" else node_id
        if name and name != node_id and element.tag != "SubTree":
            label = f"{name} ({node_id})"
        outline[len(outline) + 1] = OutlineNode(depth, node_id, label)
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
    outline: dict[int, OutlineNode] = field(default_factory=dict)

    def apply(self, record: dict[str, Any]) -> None:
        event = record.get("event")
        if event == "transition":
            path, status = str(record.get("path")), str(record.get("status"))
            self.nodes[path] = (str(record.get("node_id")), status)
            if status in ("SUCCESS", "FAILURE", "SKIPPED"):
                self.results[path] = status
        elif event == "status":
            self.root = str(record.get("root_status", self.root))
            self.ticks = int(record.get("tick_count", self.ticks) or 0)
            self.active = str(record.get("active_path", "") or "")
            self.waiting = []
        elif event == "waiting":
            self.waiting = list(record.get("missing", []))
        elif event == "error":
            self.errors.append(str(record.get("message")))
        elif event == "finished":
            self.finished = record
            self.root = str(record.get("root_status", self.root))
            self.ticks = int(record.get("tick_count", self.ticks) or self.ticks)

    def rows(self, max_lines: int = MAX_VIEW_LINES) -> list[tuple[bool, int, str, Text]]:
        """(active?, depth, label, status) of the first `max_lines - 1` nodes, in tree order."""
        base = min((p.count("/") for p in self.nodes), default=0)

        def order(path: str) -> int:
            uid = _uid(path)
            return uid if uid is not None else 1 << 30

        # Tree order when paths carry uids; the outline gives true depths when it matches the tree.
        rows = []
        for path in sorted(self.nodes, key=order)[: max(1, max_lines - 1)]:
            node_id, status = self.nodes[path]
            known = self.outline.get(order(path))
            depth = known.depth if known and known.node_id == node_id else path.count("/") - base
            shown = terminal.status_text(status)
            if status == "IDLE" and path in self.results:
                # An idle node shows what it last returned, dimmed, as Groot2 does.
                shown = Text(f"({self.results[path].lower()})", style="bright_black")
            label = node_id
            if node_id == "SubTree":
                label = f"SubTree {path.rsplit('/', 1)[-1].split('::')[0]}"
            rows.append((path == self.active, depth, label, shown))
        return rows

    def renderable(self, max_lines: int = MAX_VIEW_LINES) -> Group:
        """The footer: `tree <root>  ticks N`, then one row a node, indented by depth."""
        head = Text.assemble("tree ", terminal.status_text(self.root), f"  ticks {self.ticks}")
        if self.waiting:
            head.append(f"  waiting for node types: {', '.join(self.waiting)}")
        grid = Table.grid(padding=(0, 1))
        grid.add_column(no_wrap=True)
        grid.add_column(no_wrap=True, min_width=LABEL_WIDTH)
        grid.add_column(no_wrap=True)
        for active, depth, label, status in self.rows(max_lines):
            grid.add_row("▶" if active else " ", f"{'  ' * depth}{label}", status)
        return Group(head, grid)

    def last_statuses(self) -> dict[int, str]:
        """uid -> what each node seen last did: its last result once it went back to IDLE."""
        statuses = {}
        for path, (_node_id, status) in self.nodes.items():
            uid = _uid(path)
            if uid is not None:
                statuses[uid] = self.results.get(path, status) if status == "IDLE" else status
        return statuses

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
    """Log lines of every component and the live tree footer on one rich console.

    On a terminal the footer is a `rich.live.Live` display that log lines scroll above; off a
    terminal (or with live off) it becomes plain progress lines and nothing carries ANSI codes.
    """

    def __init__(
        self,
        stream: TextIO | None = None,
        *,
        live: bool | None = None,
        colour: bool | None = None,
        progress_interval_s: float = 2.0,
    ) -> None:
        self.rich = terminal.console(stream, colour=colour)
        self.live = self.rich.is_terminal if live is None else live
        self.progress_interval_s = progress_interval_s
        self._lock = threading.Lock()
        self._footer: Live | None = None
        self._styles: dict[str, str] = {}
        self._width = 0
        self._last_progress = ("", 0.0)

    def register(self, name: str) -> None:
        self._styles.setdefault(name, PREFIX_STYLES[len(self._styles) % len(PREFIX_STYLES)])
        self._width = max(self._width, len(name))

    def log(self, name: str, line: str) -> None:
        text = Text.assemble((f"{name:<{self._width}} | ", self._styles.get(name, "")), line.rstrip("\n"))
        with self._lock:
            self.rich.print(text, soft_wrap=True)

    def note(self, text: str) -> None:
        self.log("coral", text)

    def show(self, view: TreeView) -> None:
        if self.live:
            footer = view.renderable(max_lines=max(8, self.rich.size.height - 6))
            with self._lock:
                if self._footer is None:
                    self._footer = Live(
                        footer,
                        console=self.rich,
                        auto_refresh=False,
                        redirect_stdout=False,
                        redirect_stderr=False,
                    )
                    self._footer.start()
                self._footer.update(footer, refresh=True)
            return
        line = view.progress_line()
        now = time.monotonic()
        previous, at = self._last_progress
        root_changed = line.split(" ", 2)[:2] != previous.split(" ", 2)[:2]
        if line != previous and (root_changed or now - at >= self.progress_interval_s):
            self._last_progress = (line, now)
            self.note(line)

    def close_footer(self) -> None:
        """Stops redrawing; the last tree view stays on the screen above what follows."""
        with self._lock:
            if self._footer is not None:
                self._footer.stop()
                self._footer = None
