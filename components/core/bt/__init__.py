"""Behavior-tree engine: BehaviorTree.CPP v4 XML executed with BT.CPP's semantics on py_trees behaviours.

Executors and the SDK import from here (see the API contract): load a document, check it
(`validate_document`), build a `Tree` (`build_tree`), tick it. Plugin leaves subclass
`coral_core.bt.leaves` classes and are registered in a `NodeRegistry`.
"""

from coral_core.bt.blackboard import Blackboard
from coral_core.bt.builder import build_tree
from coral_core.bt.errors import BTError, BTLoadError, BTRuntimeError
from coral_core.bt.loader import load_tree_file, load_tree_text
from coral_core.bt.model import TreeDocument
from coral_core.bt.ports import PortSpec
from coral_core.bt.registry import NodeRegistry, NodeSpec
from coral_core.bt.status import NodeKind, PortDirection, Status
from coral_core.bt.tree import NodeState, Transition, Tree, TreeSnapshot
from coral_core.bt.validation import validate_document

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
    "build_tree",
    "load_tree_file",
    "load_tree_text",
    "validate_document",
]
