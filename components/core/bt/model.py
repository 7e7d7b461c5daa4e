"""Parsed tree model: node elements with file:line, tree definitions, SubTree port models.

Produced by the loader; consumed by the builder and the static validation. `TreeDocument` is the
object executors get from `load_tree_file`/`load_tree_text`; they check it with
`validation.validate_document` and build it with `builder.build_tree`. The model imports neither:
both import it.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from coral_core.bt.ports import PortSpec

if TYPE_CHECKING:
    from coral_core.bt.errors import BTLoadError
    from coral_core.bt.registry import NodeRegistry

RESERVED_ATTRS = frozenset(
    {
        "name",
        "ID",
        "_autoremap",
        "_failureIf",
        "_successIf",
        "_skipIf",
        "_while",
        "_onSuccess",
        "_onFailure",
        "_post",
        "_onHalted",
    }
)
PRE_CONDITIONS = ("_failureIf", "_successIf", "_skipIf", "_while")
POST_CONDITIONS = ("_onSuccess", "_onFailure", "_post", "_onHalted")


@dataclass
class NodeElement:
    node_id: str
    attrs: dict[str, str]
    file: str
    line: int
    children: list[NodeElement] = field(default_factory=list)
    tag: str = ""

    @property
    def name(self) -> str | None:
        return self.attrs.get("name")

    def walk(self) -> Iterator[NodeElement]:
        yield self
        for child in self.children:
            yield from child.walk()


@dataclass
class TreeDef:
    tree_id: str
    root: NodeElement | None
    file: str
    line: int


@dataclass
class TreeDocument:
    trees: dict[str, TreeDef]
    subtree_models: dict[str, list[PortSpec]]
    main_tree: str | None
    files: list[str]
    warnings: list[str] = field(default_factory=list)
    main_error: BTLoadError | None = None

    def main_tree_def(self) -> TreeDef:
        if self.main_error is not None:
            raise self.main_error
        assert self.main_tree is not None
        return self.trees[self.main_tree]

    def reachable_trees(self) -> list[TreeDef]:
        """The main tree and every tree its SubTree elements reach (each once, cycles tolerated)."""
        seen: dict[str, TreeDef] = {}
        stack = [self.main_tree_def()]
        while stack:
            tree = stack.pop()
            if tree.tree_id in seen:
                continue
            seen[tree.tree_id] = tree
            if tree.root is None:
                continue
            for el in tree.root.walk():
                if el.node_id == "SubTree":
                    target = self.trees.get(el.attrs.get("ID", ""))
                    if target is not None:
                        stack.append(target)
        return list(seen.values())

    def node_types_used(self) -> set[str]:
        used: set[str] = set()
        for tree in self.reachable_trees():
            if tree.root is not None:
                used.update(el.node_id for el in tree.root.walk())
        return used

    def missing_node_types(self, registry: NodeRegistry) -> list[str]:
        return sorted(n for n in self.node_types_used() if not registry.has(n))
