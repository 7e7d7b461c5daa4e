"""Snapshots of a live tree read over Groot2's protocol, and their rich rendering: the library
behind `coral tree watch` (`coral_operator.tree_cli`). One snapshot is the FULLTREE (read once per tree
UUID) joined with a STATUS reply, and optionally the blackboards.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from typing import Any

from coral_core.bt.groot2.client import Groot2Client
from coral_core.bt.groot2.protocol import IDLE_FROM
from rich.text import Text
from rich.tree import Tree as RichTree

NAMES = {0: "IDLE", 1: "RUNNING", 2: "SUCCESS", 3: "FAILURE", 4: "SKIPPED"}
STYLES = {"RUNNING": "bold yellow", "SUCCESS": "green", "FAILURE": "bold red", "SKIPPED": "dim cyan"}


@dataclass
class LiveNode:
    uid: int
    tag: str
    name: str
    path: str = ""
    status: str = "IDLE"
    after: str | None = None  # the status an IDLE node left
    children: list[LiveNode] = field(default_factory=list)

    def as_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"uid": self.uid, "tag": self.tag, "name": self.name, "status": self.status}
        if self.path:
            out["path"] = self.path
        if self.after:
            out["after"] = self.after
        out["children"] = [child.as_dict() for child in self.children]
        return out


def parse_tree(xml_text: str) -> LiveNode:
    """The node hierarchy of a FULLTREE reply, each SubTree with its instance's nodes inside."""
    root = ET.fromstring(xml_text)
    by_path = {t.get("_fullpath", ""): t for t in root.findall("BehaviorTree")}

    def build(element: ET.Element) -> LiveNode:
        if element.tag == "SubTree":
            path = element.get("_fullpath", "")
            node = LiveNode(int(element.get("_uid", "0")), "SubTree", element.get("ID", ""), path)
            inner = by_path.get(path)
            if inner is not None and len(inner):
                node.children.append(build(inner[0]))
            return node
        node = LiveNode(int(element.get("_uid", "0")), element.tag, element.get("name", element.tag))
        node.children = [build(child) for child in element]
        return node

    main = by_path.get("")
    if main is None or not len(main):
        raise ValueError("the FULLTREE reply has no main tree")
    return build(main[0])


def apply_status(node: LiveNode, codes: dict[int, int]) -> None:
    code = codes.get(node.uid, 0)
    if code >= IDLE_FROM:
        node.status, node.after = "IDLE", NAMES.get(code - IDLE_FROM)
    else:
        node.status, node.after = NAMES.get(code, str(code)), None
    for child in node.children:
        apply_status(child, codes)


def board_names(node: LiveNode, main: str) -> list[str]:
    names = [main]
    stack = [node]
    while stack:
        current = stack.pop()
        if current.tag == "SubTree":
            names.append(current.path)
        stack.extend(current.children)
    return names


class Watcher:
    """Reads snapshots from one publisher; re-reads the tree when its UUID changes."""

    def __init__(self, client: Groot2Client) -> None:
        self.client = client
        self.uuid = b""
        self.root: LiveNode | None = None
        self.main_id = ""

    def snapshot(self, blackboards: bool = False) -> dict[str, Any]:
        codes = self.client.status()
        if self.root is None or self.client.tree_uuid != self.uuid:
            xml_text = self.client.fulltree()
            self.uuid = self.client.tree_uuid
            self.root = parse_tree(xml_text)
            main = ET.fromstring(xml_text).find("BehaviorTree")
            self.main_id = main.get("ID", "") if main is not None else ""
            codes = self.client.status()
        apply_status(self.root, codes)
        out: dict[str, Any] = {"tree_uuid": self.uuid.hex(), "root_status": self.root.status}
        out["tree"] = self.root.as_dict()
        if blackboards:
            out["blackboards"] = self.client.blackboards(board_names(self.root, self.main_id)) or {}
        return out


def render(snapshot: dict[str, Any]) -> RichTree:
    def label(node: dict[str, Any]) -> Text:
        text = Text(f"{node['name']}", style=STYLES.get(node["status"], ""))
        if node["tag"] not in (node["name"], "SubTree"):
            text.append(f" ({node['tag']})", style="dim")
        if node["tag"] == "SubTree":
            text.append(f" [{node.get('path', '')}]", style="dim")
        state = node["status"] + (f" after {node['after']}" if node.get("after") else "")
        text.append(f"  {state}", style=STYLES.get(node["status"], "dim"))
        return text

    def add(branch: RichTree, node: dict[str, Any]) -> None:
        for child in node["children"]:
            add(branch.add(label(child)), child)

    top = snapshot["tree"]
    tree = RichTree(label(top))
    add(tree, top)
    return tree
