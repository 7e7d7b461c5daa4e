"""Builds node objects from a `TreeDocument`: one blackboard per SubTree instance, port checks against
the registry (file:line errors), uids in document order and BT.CPP-style full paths. Called by
`TreeDocument.build`.
"""

from __future__ import annotations

import re
from typing import Any

from coral_core.bt.anyvalue import kind_of, text_to_double
from coral_core.bt.blackboard import Blackboard, Entry, strongly_typed
from coral_core.bt.errors import BTError, BTLoadError, ScriptError
from coral_core.bt.model import POST_CONDITIONS, PRE_CONDITIONS, RESERVED_ATTRS, NodeElement, TreeDocument
from coral_core.bt.nodes.base import NodeConfig, TreeNode
from coral_core.bt.ports import (
    PortSpec,
    blackboard_key,
    convert_string,
    is_typed,
    literal_fits,
    normalize_type,
)
from coral_core.bt.registry import NodeRegistry
from coral_core.bt.runtime import Runtime
from coral_core.bt.scripting import compile_condition
from coral_core.bt.status import NodeKind, PortDirection
from coral_core.bt.tree import Tree
from coral_core.bt.validation import verify_structure

# What std::from_chars reads as a whole string: no blanks, no '+', no hex.
_WHOLE_INT = re.compile(r"-?[0-9]+")
_WHOLE_DOUBLE = re.compile(
    r"-?(?:(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?|inf(?:inity)?|nan(?:\([0-9a-zA-Z_]*\))?)",
    re.IGNORECASE,
)


# Nodes from the root to the deepest leaf, SubTrees included. A tick recurses through every level,
# and Python's stack (a thousand frames) holds about 300; real trees stay below 50.
MAX_NODE_DEPTH = 200


def literal_value(text: str) -> Any:
    """A SubTree literal as BT.CPP 4.10 stores it: an int when the whole text is one (and fits
    int64), else a double when the whole text is one, else the text (" 2", "+2" and "0x2" stay text)."""
    if _WHOLE_INT.fullmatch(text) and -(2**63) <= int(text) < 2**63:
        return int(text)
    if _WHOLE_DOUBLE.fullmatch(text):
        try:
            return text_to_double(text)
        except ValueError:  # out of double's range: from_chars refuses it too
            return text
    return text


def _async_children(el: NodeElement) -> int:
    return sum(c.node_id == "AsyncSequence" for c in el.children)


def is_port_attribute(name: str) -> bool:
    return bool(name) and name[0].isalpha() and name not in RESERVED_ATTRS


class _Builder:
    def __init__(self, doc: TreeDocument, registry: NodeRegistry, runtime: Runtime) -> None:
        self.doc = doc
        self.registry = registry
        self.runtime = runtime
        self.uid = 0
        self.nodes: list[TreeNode] = []
        self.subtree_paths: set[str] = set()

    def fail(self, el: NodeElement, message: str, path: str | None = None) -> BTLoadError:
        return BTLoadError(message, file=el.file, line=el.line, node_path=path)

    def create(
        self, el: NodeElement, board: Blackboard, prefix: str, stack: list[str], depth: int = 1
    ) -> TreeNode:
        if depth > MAX_NODE_DEPTH:
            raise self.fail(
                el,
                f"the tree nests more than {MAX_NODE_DEPTH} nodes deep through its SubTrees "
                f"({' -> '.join(stack)}); the limit is {MAX_NODE_DEPTH}",
            )
        spec = self.registry.get(el.node_id)
        if spec is None or spec.cls is None:
            raise self.fail(el, f"Node not recognized: {el.node_id}")
        self._check_children(el, spec.kind)
        self.uid += 1
        uid = self.uid
        type_id = el.attrs.get("ID", el.node_id) if spec.kind == NodeKind.SUBTREE else el.node_id
        name = el.attrs.get("name") or type_id
        path = prefix + name
        if name == type_id:
            path += f"::{uid}"
        specs = {p.name: p for p in spec.ports}
        ports: dict[str, str] = {}
        cpp_widths = spec.is_builtin
        if spec.kind != NodeKind.SUBTREE:
            for key, value in el.attrs.items():
                if not is_port_attribute(key):
                    continue
                if key not in specs:
                    raise self.fail(
                        el,
                        f"a port with name [{key}] is found in the XML (<{el.node_id}>) but "
                        "not in the providedPorts() of its registered node type",
                        path,
                    )
                ports[key] = value
            self._check_ports(el, ports, specs, board, path, cpp_widths)
        config = NodeConfig(
            el.node_id, uid, path, board, self.runtime, ports, specs, el.file, el.line, cpp_widths
        )
        try:
            node = spec.cls(name, config)
        except BTError as err:
            if err.file is None:
                raise self.fail(el, f"cannot construct {el.node_id}: {err.message}", path) from None
            raise
        except Exception as err:  # noqa: BLE001 - a plugin constructor's failure becomes a load error
            raise self.fail(el, f"cannot construct {el.node_id}: {type(err).__name__}: {err}", path) from err
        self._conditions(node, el, path)
        self.nodes.append(node)
        if spec.kind == NodeKind.SUBTREE:
            node.subtree_id = type_id
            node.subtree_remap = {k: v for k, v in el.attrs.items() if is_port_attribute(k)}
            child = self._subtree(el, board, path, stack, depth)
            node.children = [child]
            child.parent = node
        else:
            node.children = [self.create(c, board, prefix, stack, depth + 1) for c in el.children]
            for c in node.children:
                c.parent = node
        return node

    def _check_children(self, el: NodeElement, kind: NodeKind) -> None:
        count = len(el.children)
        if kind == NodeKind.CONTROL:
            need = 2 if el.node_id == "TryCatch" else 1
            if count < need:
                raise self.fail(
                    el, f"control node <{el.node_id}> needs at least {need} child(ren), has {count}"
                )
            # BT.CPP's check is meant for any async child but only counts direct AsyncSequence children.
            if el.node_id == "ReactiveSequence" and _async_children(el) > 1:
                raise self.fail(el, "A ReactiveSequence cannot have more than one async child.")
        elif kind == NodeKind.DECORATOR:
            if count != 1:
                raise self.fail(el, f"decorator <{el.node_id}> needs exactly 1 child, has {count}")
        elif count != 0:
            what = "<SubTree>" if kind == NodeKind.SUBTREE else f"leaf <{el.node_id}>"
            raise self.fail(el, f"{what} may not have children, has {count}")

    def _check_ports(
        self,
        el: NodeElement,
        ports: dict[str, str],
        specs: dict[str, PortSpec],
        board: Blackboard,
        path: str,
        cpp_widths: bool,
    ) -> None:
        for name, spec in specs.items():
            raw = ports.get(name, spec.default)
            if raw is None:
                continue
            type_name = normalize_type(spec.type)
            key = blackboard_key(raw)
            if key == "=":
                key = name
            if key is None:
                # BT.CPP checks literals when the tree loads, except a NodeStatus: that one fails
                # ("Missing parameter") when the node reads it.
                checked = is_typed(type_name) and type_name != "NodeStatus"
                if spec.direction != PortDirection.OUTPUT and checked and name in ports:
                    try:
                        value = convert_string(raw, type_name, self.runtime.enums)
                    except ValueError as err:
                        raise self.fail(el, f"port [{name}]: {err}", path) from None
                    if not literal_fits(value, spec.type, cpp_widths):
                        raise self.fail(
                            el,
                            f'The port with name "{name}" and value "{raw}" can not be converted '
                            f"to {spec.type}",
                            path,
                        )
                continue
            existing = board.get_entry(key)
            if existing is None:
                # BT.CPP creates every remapped entry (empty, declared with the port's type) at
                # construction; an entry a first port left untyped is never typed later on.
                try:
                    created = board.create_entry(key, type_name)
                except ScriptError as err:
                    raise self.fail(el, err.message, path) from None
                if cpp_widths and created.type == type_name:
                    created.cpp_type = spec.type
            elif (
                strongly_typed(existing.type)
                and strongly_typed(type_name)
                and existing.type != type_name
                and existing.type != "string"
            ):
                raise self.fail(
                    el,
                    f"The creation of the tree failed because the port [{key}] was initially "
                    f"created with type [{existing.type}] and, later type [{type_name}] was used "
                    "somewhere else.",
                    path,
                )

    def _conditions(self, node: TreeNode, el: NodeElement, path: str) -> None:
        pre: list[tuple[int, Any]] = []
        post: dict[str, Any] = {}
        for index, attr in enumerate(PRE_CONDITIONS):
            if attr in el.attrs:
                pre.append((index, self._script(el, attr, path)))
        for attr in POST_CONDITIONS:
            if attr in el.attrs:
                post[attr] = self._script(el, attr, path)
        node._pre = pre or None
        node._post = post or None
        node._script_sources = {a: el.attrs[a] for a in PRE_CONDITIONS + POST_CONDITIONS if a in el.attrs}

    def _script(self, el: NodeElement, attr: str, path: str) -> Any:
        try:
            return compile_condition(el.attrs[attr])
        except ScriptError as err:
            raise self.fail(el, f"invalid script in {attr}: {err.message}", path) from None

    def _subtree(
        self, el: NodeElement, board: Blackboard, path: str, stack: list[str], depth: int
    ) -> TreeNode:
        tree_id = el.attrs.get("ID", "")
        target = self.doc.trees.get(tree_id)
        if target is None or target.root is None:
            raise self.fail(el, f"SubTree [{tree_id}] is not defined", path)
        if tree_id in stack:
            raise self.fail(
                el, "Recursive behavior tree cycle detected: " + " -> ".join(stack + [tree_id]), path
            )
        if path in self.subtree_paths:
            raise self.fail(el, f"Duplicate SubTree path detected: '{path}'. Use a different name.", path)
        self.subtree_paths.add(path)
        autoremap = el.attrs.get("_autoremap", "false").strip().lower() in ("true", "1")
        child_board = Blackboard(parent=board, autoremap=autoremap)
        given = {k: v for k, v in el.attrs.items() if k not in ("ID", "name") and is_port_attribute(k)}
        for port in self.doc.subtree_models.get(tree_id, []):
            if port.name in given:
                continue
            if port.default is not None:
                given[port.name] = port.default
            elif not autoremap:
                raise self.fail(
                    el,
                    f"SubTree [{tree_id}] is defining a mandatory port called [{port.name}], "
                    "but you are not remapping it",
                    path,
                )
        for key, value in given.items():
            target_key = blackboard_key(value)
            if target_key == "=":
                target_key = key
            if target_key is not None:
                # Only an alias: the caller's entry appears when something writes through it.
                child_board.remap[key] = target_key
            else:
                # A literal stays in the subtree's own board, even with _autoremap; 4.10 declares
                # a numeric one with its number type, text stays untyped.
                literal = literal_value(value)
                entry = Entry("any" if isinstance(literal, str) else kind_of(literal), literal)
                entry.touch()
                child_board.storage[key] = entry
        return self.create(target.root, child_board, path + "/", stack + [tree_id], depth + 1)


def build_tree(
    doc: TreeDocument,
    registry: NodeRegistry,
    *,
    blackboard: dict[str, Any] | None = None,
    clock: Any = None,
    context: object = None,
) -> Tree:
    main = doc.main_tree_def()
    if main.root is None:
        raise BTLoadError(f"BehaviorTree [{main.tree_id}] is empty", file=main.file, line=main.line)
    runtime = Runtime(dict(registry.enums), context=context, clock=clock)
    root_board = Blackboard(enums=runtime.enums)
    for key, value in (blackboard or {}).items():
        root_board.set(key, value)
    verify_structure(doc, registry)
    builder = _Builder(doc, registry, runtime)
    root = builder.create(main.root, root_board, "", [main.tree_id])
    tree = Tree(root, runtime, root_board, builder.nodes, doc.warnings)
    tree.main_tree_id = main.tree_id
    return tree
