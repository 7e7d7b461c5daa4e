"""Loads BT.CPP v4 (and v3) XML into a `TreeDocument`: documents, `<include>`s relative to the including
file with cycle detection, BT.CPP's main-tree rules, compact/explicit syntax, `<TreeNodesModel>` SubTree
port defaults, and v3 names converted with warnings. Entry points: `load_tree_file`, `load_tree_text`.

Includes are read from the filesystem unless the caller injects an `IncludeResolver`: whoever loads
trees on someone else's behalf (the operator) resolves them among the files it was given instead.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable
from dataclasses import dataclass, field

from coral_core import parsing
from coral_core.bt.errors import BTLoadError
from coral_core.bt.limits import IncludeBudget, check_document
from coral_core.bt.model import NodeElement, TreeDef, TreeDocument
from coral_core.bt.ports import PortSpec
from coral_core.bt.registry import V3_SOURCE, NodeRegistry
from coral_core.bt.status import PortDirection
from coral_core.bt.xml_lenient import XmlElement, parse_xml

log = logging.getLogger(__name__)

_EXPLICIT = {"Action", "Condition", "Control", "Decorator"}
_V3_RENAMES = {
    "SequenceStar": "SequenceWithMemory",
    "RetryUntilSuccesful": "RetryUntilSuccessful",
    "SubTreePlus": "SubTree",
}
_V3_MARKERS = (
    "SequenceStar",
    "SubTreePlus",
    "__shared_blackboard",
    "RetryUntilSuccesful",
    "BlackboardCheck",
    "success_threshold",
)
_PORT_TAGS = {
    "input_port": PortDirection.INPUT,
    "output_port": PortDirection.OUTPUT,
    "inout_port": PortDirection.INOUT,
}

IncludeResolver = Callable[[str, str, int], tuple[str, str]]
"""(path attribute, including file, line) -> (name of the included file, its text); raises BTLoadError."""


@dataclass
class _State:
    registry: NodeRegistry | None
    trees: dict[str, TreeDef] = field(default_factory=dict)
    models: dict[str, list[PortSpec]] = field(default_factory=dict)
    files: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    stack: list[str] = field(default_factory=list)
    unnamed: int = 0
    resolve_include: IncludeResolver | None = None
    budget: IncludeBudget = field(default_factory=IncludeBudget)

    def warn(self, file: str, line: int, message: str) -> None:
        text = f"{file}:{line}: {message}"
        self.warnings.append(text)
        log.warning(text)


def load_tree_file(
    path: str | os.PathLike[str], registry: NodeRegistry | None = None, *, main_tree: str | None = None
) -> TreeDocument:
    path = os.path.abspath(os.fspath(path))
    try:
        text = parsing.read_text(path)
    except OSError as err:
        raise BTLoadError(f"cannot read tree file: {err.strerror}", file=path) from None
    except parsing.NotText as err:
        raise BTLoadError(err.reason, file=path, line=err.line) from None
    return _load(text, path, os.path.dirname(path), registry, main_tree)


def load_tree_text(
    text: str,
    registry: NodeRegistry | None = None,
    *,
    filename: str = "<string>",
    main_tree: str | None = None,
    resolve_include: IncludeResolver | None = None,
) -> TreeDocument:
    return _load(text, filename, os.getcwd(), registry, main_tree, resolve_include)


def _load(
    text: str,
    filename: str,
    base_dir: str,
    registry: NodeRegistry | None,
    main_tree: str | None,
    resolve_include: IncludeResolver | None = None,
) -> TreeDocument:
    state = _State(registry, resolve_include=resolve_include)
    root = _parse_document(text, filename, base_dir, state)
    doc = TreeDocument(state.trees, state.models, None, state.files, state.warnings)
    wanted = main_tree or root.get("main_tree_to_execute")
    if wanted:
        wanted = wanted.strip()
        if wanted not in state.trees:
            doc.main_error = BTLoadError(
                f"main tree [{wanted}] is not defined", file=filename, line=root.line
            )
        doc.main_tree = wanted
    elif len(state.trees) == 1:
        doc.main_tree = next(iter(state.trees))
    elif not state.trees:
        doc.main_error = BTLoadError(
            "no <BehaviorTree> defined ([main_tree_to_execute] was not specified correctly)",
            file=filename,
            line=root.line,
        )
    else:
        doc.main_error = BTLoadError(
            "[main_tree_to_execute] was not specified correctly: the document "
            f"defines {len(state.trees)} trees; name one with main_tree=",
            file=filename,
            line=root.line,
        )
    if doc.main_error is not None:
        raise doc.main_error
    return doc


def _parse_document(text: str, filename: str, base_dir: str, state: _State) -> XmlElement:
    # Size, element count and nesting first, so no document can exhaust memory or the stack.
    check_document(text, filename, state.budget)
    root = parse_xml(text, filename)
    if root.tag != "root":
        raise BTLoadError("The XML must have a root node called <root>", file=filename, line=root.line)
    state.files.append(filename)
    fmt = root.get("BTCPP_format")
    v3 = fmt is not None and fmt.strip() == "3"
    if fmt is None:
        state.warn(filename, root.line, 'the root should contain the attribute [BTCPP_format="4"]')
        v3 = any(marker in text for marker in _V3_MARKERS)
        if v3:
            state.warn(filename, root.line, "the document uses BT.CPP v3 constructs: loaded as format 3")
    state.stack.append(filename)
    try:
        for child in root.children:
            if child.tag == "include":
                _include(child, filename, base_dir, state)
        models_seen = 0
        for child in root.children:
            if child.tag == "BehaviorTree":
                _tree(child, filename, root, state, v3)
            elif child.tag == "TreeNodesModel":
                models_seen += 1
                if models_seen > 1:
                    raise BTLoadError(
                        "Only a single node <TreeNodesModel> is supported", file=filename, line=child.line
                    )
                _models(child, filename, state)
            elif child.tag != "include":
                state.warn(filename, child.line, f"ignoring unknown element <{child.tag}> under <root>")
    finally:
        state.stack.pop()
    return root


def _include(el: XmlElement, filename: str, base_dir: str, state: _State) -> None:
    rel = el.get("path")
    if not rel:
        raise BTLoadError("<include> needs a path attribute", file=filename, line=el.line)
    if el.get("ros_pkg"):
        raise BTLoadError(
            f'<include ros_pkg="{el.get("ros_pkg")}"> needs a ROS package index, which is not available here',
            file=filename,
            line=el.line,
        )
    state.budget.count_include(filename, el.line)
    if state.resolve_include is not None:
        target, text = state.resolve_include(rel, filename, el.line)
        if target in state.stack:
            chain = " -> ".join(state.stack + [target])
            raise BTLoadError(f"include cycle: {chain}", file=filename, line=el.line)
        _parse_document(text, target, base_dir, state)
        return
    target = rel if os.path.isabs(rel) else os.path.join(base_dir, rel)
    target = os.path.abspath(target)
    if target in state.stack:
        chain = " -> ".join(state.stack + [target])
        raise BTLoadError(f"include cycle: {chain}", file=filename, line=el.line)
    try:
        text = parsing.read_text(target)
    except OSError as err:
        raise BTLoadError(
            f"cannot read included file [{rel}]: {err.strerror}", file=filename, line=el.line
        ) from None
    except parsing.NotText as err:
        raise BTLoadError(err.reason, file=target, line=err.line) from None
    _parse_document(text, target, os.path.dirname(target), state)


def _tree(el: XmlElement, filename: str, root: XmlElement, state: _State, v3: bool) -> None:
    tree_id = el.get("ID")
    if tree_id is None:
        tree_id = f"BehaviorTree_{state.unnamed}"
        state.unnamed += 1
    if any(ch in tree_id for ch in " \t"):
        state.warn(
            filename, el.line, f"tree ID '{tree_id}' contains spaces (accepted; BT.CPP >= 4.9 rejects it)"
        )
    if tree_id in state.trees:
        raise BTLoadError(f"BehaviorTree [{tree_id}] is defined twice", file=filename, line=el.line)
    if state.registry is not None and state.registry.has(tree_id):
        raise BTLoadError(
            f"BehaviorTree ID [{tree_id}] is the name of a registered node type", file=filename, line=el.line
        )
    if len(el.children) != 1:
        raise BTLoadError(
            f"BehaviorTree [{tree_id}] must have exactly one child, it has {len(el.children)}",
            file=filename,
            line=el.line,
        )
    state.trees[tree_id] = TreeDef(tree_id, _node(el.children[0], filename, state, v3), filename, el.line)


def _node(el: XmlElement, filename: str, state: _State, v3: bool) -> NodeElement:
    attrs = dict(el.attrib)
    if el.tag in _EXPLICIT:
        node_id = attrs.pop("ID", None)
        if not node_id:
            raise BTLoadError(f"<{el.tag}> needs an ID attribute", file=filename, line=el.line)
    else:
        node_id = el.tag
        if "ID" in attrs and node_id not in ("SubTree", "SubTreePlus"):
            raise BTLoadError(
                f"attribute ID is not allowed on <{el.tag}> (compact syntax)", file=filename, line=el.line
            )
    registered = state.registry is not None and state.registry.has(node_id)
    if node_id in _V3_RENAMES and not registered:
        new_id = _V3_RENAMES[node_id]
        state.warn(filename, el.line, f"v3 node <{node_id}> loaded as <{new_id}>")
        if node_id == "SubTreePlus" and "__autoremap" in attrs:
            attrs["_autoremap"] = attrs.pop("__autoremap")
        node_id = new_id
    elif node_id == "SubTree" and v3:
        _v3_subtree(attrs, filename, el.line, state)
    elif node_id == "Parallel" and ("success_threshold" in attrs or "failure_threshold" in attrs):
        state.warn(
            filename,
            el.line,
            "v3 Parallel ports success_threshold/failure_threshold renamed to success_count/failure_count",
        )
        if "success_threshold" in attrs:
            attrs["success_count"] = attrs.pop("success_threshold")
        if "failure_threshold" in attrs:
            attrs["failure_count"] = attrs.pop("failure_threshold")
    elif node_id.startswith("BlackboardCheck") and _is_v3_compat(state, node_id):
        state.warn(
            filename, el.line, f"v3 node <{node_id}> is deprecated; use Precondition or ScriptCondition"
        )
    if node_id == "SubTree" and "__shared_blackboard" in attrs:
        shared = attrs.pop("__shared_blackboard")
        attrs.setdefault("_autoremap", shared)
        state.warn(filename, el.line, "v3 attribute __shared_blackboard loaded as _autoremap")
    children = [_node(c, filename, state, v3) for c in el.children]
    return NodeElement(node_id, attrs, filename, el.line, children, el.tag)


def _is_v3_compat(state: _State, node_id: str) -> bool:
    spec = state.registry.get(node_id) if state.registry is not None else None
    return spec is None or spec.source == V3_SOURCE


def _v3_subtree(attrs: dict[str, str], filename: str, line: int, state: _State) -> None:
    changed = False
    for key, value in list(attrs.items()):
        if key in ("ID", "name") or key.startswith("_"):
            continue
        stripped = value.strip()
        if not (stripped.startswith("{") and stripped.endswith("}")):
            attrs[key] = "{" + stripped + "}"
            changed = True
    if changed:
        state.warn(filename, line, "v3 SubTree port values name parent keys: wrapped in {}")


def _models(el: XmlElement, filename: str, state: _State) -> None:
    for model in el.children:
        if model.tag != "SubTree":
            continue
        model_id = model.get("ID")
        if not model_id:
            raise BTLoadError("<SubTree> model needs an ID", file=filename, line=model.line)
        ports: list[PortSpec] = []
        for port in model.children:
            direction = _PORT_TAGS.get(port.tag)
            if direction is None:
                continue
            name = port.get("name")
            if not name:
                raise BTLoadError(f"<{port.tag}> needs a name", file=filename, line=port.line)
            ports.append(
                PortSpec(
                    name, direction, port.get("type") or "any", port.get("default"), (port.text or "").strip()
                )
            )
        state.models[model_id] = ports
