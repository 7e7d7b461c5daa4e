"""Behavior-tree engine: BehaviorTree.CPP v4 XML executed with BT.CPP's semantics on py_trees behaviours.

Executors and the SDK import from here (see the API contract): load a document, build a `Tree`,
tick it. Plugin leaves subclass `coral.bt.leaves` classes and are registered in a `NodeRegistry`.
"""

from coral.bt.blackboard import Blackboard
from coral.bt.errors import BTError, BTLoadError, BTRuntimeError
from coral.bt.loader import load_tree_file, load_tree_text
from coral.bt.model import TreeDocument
from coral.bt.ports import PortSpec
from coral.bt.registry import NodeRegistry, NodeSpec
from coral.bt.status import NodeKind, PortDirection, Status
from coral.bt.tree import NodeState, Transition, Tree, TreeSnapshot

__all__ = [
    "BTError",
    "BTLoadError",
    "BTRuntimeError",
    "Blackboard",
    "NodeKind",
    "NodeRegistry",
    "NodeSpec",
    "NodeState",
    "PortDirection",
    "PortSpec",
    "Status",
    "Transition",
    "Tree",
    "TreeDocument",
    "TreeSnapshot",
    "load_tree_file",
    "load_tree_text",
]
