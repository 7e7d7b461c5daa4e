"""Static validation of a `TreeDocument` against a registry: every problem with file:line, without
building. Reports unknown node types, undeclared or mistyped ports, mandatory SubTree ports not
remapped, required ports left out (BT.CPP fails only at the first tick), SubTree cycles, wrong child
counts and invalid scripts. Called by `TreeDocument.validate`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from coral_core.bt.errors import BTLoadError, ScriptError
from coral_core.bt.model import POST_CONDITIONS, PRE_CONDITIONS, NodeElement
from coral_core.bt.ports import (
    blackboard_key,
    convert_string,
    has_trailing_text,
    is_typed,
    literal_fits,
    normalize_type,
)
from coral_core.bt.scripting import compile_condition, compile_script
from coral_core.bt.status import NodeKind, PortDirection

if TYPE_CHECKING:
    from coral_core.bt.model import TreeDocument
    from coral_core.bt.registry import NodeRegistry

_SCRIPT_PORTS = {("Script", "code"), ("ScriptCondition", "code"), ("Precondition", "if")}
_FIXED_CHILDREN = {
    "IfThenElse": (2, 3),
    "WhileDoElse": (2, 3),
    **{f"Switch{n}": (n + 1, n + 1) for n in range(2, 7)},
}


def verify_structure(doc: TreeDocument, registry: NodeRegistry) -> None:
    """BT.CPP's load-time check of every `<BehaviorTree>` in the document, instantiated or not:
    known node types and child counts. Raises the first problem as a BTLoadError."""
    for tree in doc.trees.values():
        if tree.root is None:
            raise BTLoadError(
                f'The node <BehaviorTree ID="{tree.tree_id}"> must have exactly 1 child',
                file=tree.file,
                line=tree.line,
            )
        for el in tree.root.walk():
            spec = registry.get(el.node_id)
            if spec is None:
                raise _err(el, f"Node not recognized: {el.node_id}")
            n = len(el.children)
            if spec.kind == NodeKind.DECORATOR and n != 1:
                raise _err(el, f"decorator <{el.node_id}> needs exactly 1 child, has {n}")
            if spec.kind == NodeKind.CONTROL and n == 0:
                raise _err(el, f"control node <{el.node_id}> needs at least 1 child(ren), has 0")
            if spec.kind in (NodeKind.ACTION, NodeKind.CONDITION, NodeKind.SUBTREE) and n:
                raise _err(el, f"<{el.node_id}> may not have children, has {n}")


def validate_document(doc: TreeDocument, registry: NodeRegistry) -> list[BTLoadError]:
    """Every problem in every `<BehaviorTree>` of the document (not only the main tree's)."""
    errors: list[BTLoadError] = []
    for tree in doc.trees.values():
        if tree.root is not None:
            for el in tree.root.walk():
                errors.extend(_check_element(el, doc, registry))
    errors.extend(_cycles(doc))
    return errors


def _err(el: NodeElement, message: str) -> BTLoadError:
    return BTLoadError(message, file=el.file, line=el.line, node_path=el.name)


def _check_element(el: NodeElement, doc: TreeDocument, registry: NodeRegistry) -> list[BTLoadError]:
    out: list[BTLoadError] = []
    spec = registry.get(el.node_id)
    if spec is None:
        return [_err(el, f"Node not recognized: {el.node_id}")]
    n = len(el.children)
    if spec.kind == NodeKind.CONTROL:
        low, high = _FIXED_CHILDREN.get(el.node_id, (2 if el.node_id == "TryCatch" else 1, 10**9))
        if not low <= n <= high:
            out.append(
                _err(
                    el,
                    f"<{el.node_id}> has {n} children; it needs "
                    + (f"{low}" if low == high else f"{low}..{high}" if high < 10**9 else f">= {low}"),
                )
            )
    elif spec.kind == NodeKind.DECORATOR and n != 1:
        out.append(_err(el, f"decorator <{el.node_id}> needs exactly 1 child, has {n}"))
    elif spec.kind in (NodeKind.ACTION, NodeKind.CONDITION, NodeKind.SUBTREE) and n:
        out.append(_err(el, f"<{el.node_id}> may not have children, has {n}"))
    for attr in PRE_CONDITIONS + POST_CONDITIONS:
        if attr in el.attrs:
            try:
                compile_condition(el.attrs[attr])
            except ScriptError as err:
                out.append(_err(el, f"invalid script in {attr}: {err.message}"))
    if spec.kind == NodeKind.SUBTREE:
        return out + _check_subtree(el, doc)
    specs = {p.name: p for p in spec.ports}
    for port in spec.ports:
        if port.required and port.name not in el.attrs:
            out.append(_err(el, f"<{el.node_id}> needs the port [{port.name}]; it has no default"))
    for key, value in el.attrs.items():
        if not key[:1].isalpha() or key in ("name", "ID"):
            continue
        port = specs.get(key)
        if port is None:
            out.append(
                _err(
                    el,
                    f"a port with name [{key}] is found in the XML (<{el.node_id}>) but not in "
                    "the providedPorts() of its registered node type",
                )
            )
            continue
        if (el.node_id, key) in _SCRIPT_PORTS and blackboard_key(value) is None:
            try:
                compile_script(value)
            except ScriptError as err:
                out.append(_err(el, f"invalid script in [{key}]: {err.message}"))
            continue
        type_name = normalize_type(port.type)
        if blackboard_key(value) is None and port.direction != PortDirection.OUTPUT and is_typed(type_name):
            try:
                converted = convert_string(value, type_name, registry.enums)
            except ValueError as err:
                out.append(_err(el, f"port [{key}] expects {port.type}: {err}"))
                continue
            if not literal_fits(converted, port.type, spec.is_builtin):
                out.append(_err(el, f"port [{key}] expects {port.type}: '{value}' is out of its range"))
            else:
                # BT.CPP would silently use the numeric prefix; the static check points it out.
                if value.strip() not in registry.enums and has_trailing_text(value, type_name):
                    out.append(_err(el, f"port [{key}] expects {port.type}: '{value}' has trailing text"))
        if blackboard_key(value) is None and port.direction == PortDirection.OUTPUT:
            out.append(_err(el, f"output port [{key}] must name a blackboard entry like {{{key}}}"))
    return out


def _check_subtree(el: NodeElement, doc: TreeDocument) -> list[BTLoadError]:
    tree_id = el.attrs.get("ID", "")
    if tree_id not in doc.trees:
        return [_err(el, f"SubTree [{tree_id}] is not defined")]
    autoremap = el.attrs.get("_autoremap", "false").strip().lower() in ("true", "1")
    out = []
    for port in doc.subtree_models.get(tree_id, []):
        if port.name not in el.attrs and port.default is None and not autoremap:
            out.append(
                _err(
                    el,
                    f"SubTree [{tree_id}] is defining a mandatory port called [{port.name}], "
                    "but you are not remapping it",
                )
            )
    return out


def _cycles(doc: TreeDocument) -> list[BTLoadError]:
    out: list[BTLoadError] = []
    reported: set[str] = set()

    def visit(tree_id: str, stack: list[str]) -> None:
        tree = doc.trees.get(tree_id)
        if tree is None or tree.root is None:
            return
        for el in tree.root.walk():
            if el.node_id != "SubTree":
                continue
            target = el.attrs.get("ID", "")
            if target in stack:
                if target not in reported:
                    reported.add(target)
                    out.append(
                        _err(el, "Recursive behavior tree cycle detected: " + " -> ".join(stack + [target]))
                    )
                continue
            visit(target, stack + [target])

    if doc.main_tree is not None:
        visit(doc.main_tree, [doc.main_tree])
    return out
