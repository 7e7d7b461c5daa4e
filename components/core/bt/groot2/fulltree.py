"""The FULLTREE reply: the instantiated tree as BT.CPP's `WriteTreeToXML(tree, true, true)` writes it.

One `<BehaviorTree ID _fullpath>` per subtree instance (the main tree first, then each SubTree
instance in the order it was built), every node with `name` (a SubTree with `ID` and `_fullpath`
instead), `_uid`, its ports with the defaults of its model filled in, and its pre/post-condition
scripts; then a `<TreeNodesModel>` of the node types the tree uses. Also lists the subtree
instances, which the status buffer and the blackboard dump follow. Pure; called once per
publisher.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from coral_core.bt.model import POST_CONDITIONS, PRE_CONDITIONS
from coral_core.bt.ports import blackboard_key
from coral_core.bt.status import PortDirection
from coral_core.bt.treenodesmodel import build_tree_nodes_model

if TYPE_CHECKING:
    from coral_core.bt.blackboard import Blackboard
    from coral_core.bt.nodes.base import TreeNode
    from coral_core.bt.tree import Tree


@dataclass
class SubtreeInstance:
    """BT.CPP's `Tree::Subtree`: its path ("" for the main tree), tree ID, board and nodes."""

    path: str
    tree_id: str
    board: Blackboard
    root: TreeNode
    nodes: list[TreeNode] = field(default_factory=list)

    @property
    def name(self) -> str:
        """The name a blackboard request uses: the path, or the tree ID for the main tree."""
        return self.path or self.tree_id


def is_subtree(node: TreeNode) -> bool:
    return getattr(node, "subtree_id", None) is not None


def subtree_instances(tree: Tree) -> list[SubtreeInstance]:
    """Every subtree instance in BT.CPP's order: an instance comes before those it contains."""
    out: list[SubtreeInstance] = []

    def collect(root: TreeNode, path: str, tree_id: str) -> None:
        instance = SubtreeInstance(path, tree_id, root.board, root)
        out.append(instance)
        inner: list[TreeNode] = []
        stack = [root]
        while stack:
            node = stack.pop()
            instance.nodes.append(node)
            if is_subtree(node):
                inner.append(node)
                continue
            stack.extend(reversed(node.children))
        for node in inner:
            collect(node.children[0], node.path, node.subtree_id)

    collect(tree.root, "", tree.main_tree_id)
    return out


def shown_ports(node: TreeNode) -> dict[str, str]:
    """The node's `input_ports` then `output_ports` as BT.CPP fills them: what the XML gives,
    input defaults, and output defaults that are blackboard pointers."""
    if is_subtree(node):
        return dict(node.subtree_remap)
    inputs: dict[str, str] = {}
    outputs: dict[str, str] = {}
    for name, spec in node.port_specs.items():
        given = node.ports.get(name)
        if given is not None:
            if spec.direction != PortDirection.OUTPUT:
                inputs[name] = given
            if spec.direction != PortDirection.INPUT:
                outputs[name] = given
        elif spec.default:
            if spec.direction != PortDirection.OUTPUT:
                inputs[name] = spec.default
            if spec.direction != PortDirection.INPUT and blackboard_key(spec.default) is not None:
                outputs[name] = spec.default
    return inputs | {k: v for k, v in outputs.items() if k not in inputs}


def _element(node: TreeNode, parent: ET.Element) -> None:
    if is_subtree(node):
        attrs = {"ID": node.subtree_id, "_fullpath": node.path}
        tag = "SubTree"
    else:
        attrs = {"name": node.name}
        tag = node.node_id
    attrs["_uid"] = str(node.uid)
    attrs.update(shown_ports(node))
    sources = node._script_sources
    for attr in PRE_CONDITIONS + POST_CONDITIONS:
        if attr in sources:
            attrs[attr] = sources[attr]
    element = ET.SubElement(parent, tag, attrs)
    if not is_subtree(node):
        for child in node.children:
            _element(child, element)


@dataclass
class _Model:
    id: str
    kind: str
    ports: list


def build_fulltree_xml(tree: Tree, instances: list[SubtreeInstance]) -> str:
    root = ET.Element("root", {"BTCPP_format": "4"})
    for instance in instances:
        element = ET.SubElement(root, "BehaviorTree", {"ID": instance.tree_id, "_fullpath": instance.path})
        _element(instance.root, element)
    models: dict[str, _Model] = {}
    for node in tree.nodes:
        if is_subtree(node) or node.node_id in models:
            continue
        models[node.node_id] = _Model(node.node_id, str(node.KIND), list(node.port_specs.values()))
    model_doc = ET.fromstring(build_tree_nodes_model(models.values()))
    root.append(model_doc.find("TreeNodesModel"))  # type: ignore[arg-type]
    ET.indent(root, space="    ")
    return ET.tostring(root, encoding="unicode").replace(" />", "/>") + "\n"
