"""Registry of node types (built-ins and plugins) with their kinds and declared ports, plus the
scripting enum registry. The loader/builder/validation read it; executors register plugins in it."""

from __future__ import annotations

from dataclasses import dataclass, field

from coral_core.bt import treenodesmodel
from coral_core.bt.errors import BTError
from coral_core.bt.nodes import actions, board_decorators, branching, controls, decorators, parallel, timed
from coral_core.bt.nodes.base import TreeNode
from coral_core.bt.ports import PortSpec
from coral_core.bt.status import NodeKind

BUILTIN_SOURCE = "builtin"
V3_SOURCE = "v3-compat"


@dataclass
class NodeSpec:
    id: str
    kind: NodeKind
    ports: list[PortSpec] = field(default_factory=list)
    source: str | None = None
    cls: type[TreeNode] | None = None

    @property
    def is_builtin(self) -> bool:
        """One of BT.CPP's own nodes (or a v3 name for one), not a plugin's: its integer ports have
        C++ widths (`ports.fits_integer`)."""
        return self.source in (BUILTIN_SOURCE, V3_SOURCE)

    def port(self, name: str) -> PortSpec | None:
        for p in self.ports:
            if p.name == name:
                return p
        return None


def _builtins() -> list[tuple[str, type[TreeNode], NodeKind, str]]:
    c, d, a = NodeKind.CONTROL, NodeKind.DECORATOR, NodeKind.ACTION
    table: list[tuple[str, type[TreeNode], NodeKind, str]] = [
        ("Sequence", controls.Sequence, c, BUILTIN_SOURCE),
        ("AsyncSequence", controls.AsyncSequence, c, BUILTIN_SOURCE),
        ("SequenceWithMemory", controls.SequenceWithMemory, c, BUILTIN_SOURCE),
        ("ReactiveSequence", controls.ReactiveSequence, c, BUILTIN_SOURCE),
        ("Fallback", controls.Fallback, c, BUILTIN_SOURCE),
        ("AsyncFallback", controls.AsyncFallback, c, BUILTIN_SOURCE),
        ("ReactiveFallback", controls.ReactiveFallback, c, BUILTIN_SOURCE),
        ("Parallel", parallel.Parallel, c, BUILTIN_SOURCE),
        ("ParallelAll", parallel.ParallelAll, c, BUILTIN_SOURCE),
        ("IfThenElse", branching.IfThenElse, c, BUILTIN_SOURCE),
        ("WhileDoElse", branching.WhileDoElse, c, BUILTIN_SOURCE),
        ("TryCatch", branching.TryCatch, c, BUILTIN_SOURCE),
        ("Inverter", decorators.Inverter, d, BUILTIN_SOURCE),
        ("ForceSuccess", decorators.ForceSuccess, d, BUILTIN_SOURCE),
        ("ForceFailure", decorators.ForceFailure, d, BUILTIN_SOURCE),
        ("KeepRunningUntilFailure", decorators.KeepRunningUntilFailure, d, BUILTIN_SOURCE),
        ("Repeat", decorators.Repeat, d, BUILTIN_SOURCE),
        ("RetryUntilSuccessful", decorators.RetryUntilSuccessful, d, BUILTIN_SOURCE),
        ("RunOnce", decorators.RunOnce, d, BUILTIN_SOURCE),
        ("Precondition", decorators.Precondition, d, BUILTIN_SOURCE),
        ("SkipUnlessUpdated", board_decorators.SkipUnlessUpdated, d, BUILTIN_SOURCE),
        ("WaitValueUpdate", board_decorators.WaitValueUpdate, d, BUILTIN_SOURCE),
        ("Timeout", timed.Timeout, d, BUILTIN_SOURCE),
        ("Delay", timed.Delay, d, BUILTIN_SOURCE),
        ("SubTree", decorators.SubTreeNode, NodeKind.SUBTREE, BUILTIN_SOURCE),
        ("AlwaysSuccess", actions.AlwaysSuccess, a, BUILTIN_SOURCE),
        ("AlwaysFailure", actions.AlwaysFailure, a, BUILTIN_SOURCE),
        ("Script", actions.Script, a, BUILTIN_SOURCE),
        ("ScriptCondition", actions.ScriptCondition, NodeKind.CONDITION, BUILTIN_SOURCE),
        ("SetBlackboard", actions.SetBlackboard, a, BUILTIN_SOURCE),
        ("UnsetBlackboard", actions.UnsetBlackboard, a, BUILTIN_SOURCE),
        ("WasEntryUpdated", actions.WasEntryUpdated, NodeKind.CONDITION, BUILTIN_SOURCE),
        ("Sleep", actions.Sleep, a, BUILTIN_SOURCE),
    ]
    table += [(k, v, c, BUILTIN_SOURCE) for k, v in branching.SWITCHES.items()]
    table += [(k, v, d, BUILTIN_SOURCE) for k, v in board_decorators.LOOPS.items()]
    table += [(k, v, d, V3_SOURCE) for k, v in board_decorators.BLACKBOARD_CHECKS.items()]
    return table


class NodeRegistry:
    def __init__(self) -> None:
        self._specs: dict[str, NodeSpec] = {}
        self.enums: dict[str, int] = {}

    @classmethod
    def with_builtins(cls) -> NodeRegistry:
        reg = cls()
        for node_id, node_cls, kind, source in _builtins():
            reg.register(node_id, node_cls, kind=kind, source=source)
        return reg

    def register(
        self,
        node_id: str,
        cls: type[TreeNode],
        kind: NodeKind | str | None = None,
        ports: list[PortSpec] | None = None,
        source: str | None = None,
    ) -> NodeSpec:
        if not node_id:
            raise BTError("node type ID may not be empty")
        if node_id in self._specs:
            raise BTError(f"node type [{node_id}] is already registered")
        node_kind = NodeKind(kind) if kind is not None else NodeKind(getattr(cls, "KIND", NodeKind.ACTION))
        port_list = list(ports if ports is not None else getattr(cls, "PORTS", []))
        names = [p.name for p in port_list]
        for name in names:
            if not name or name[0].isdigit():
                raise BTError(f"node type [{node_id}]: invalid port name '{name}'")
        if len(set(names)) != len(names):
            raise BTError(f"node type [{node_id}] declares the same port twice")
        spec = NodeSpec(node_id, node_kind, port_list, source, cls)
        self._specs[node_id] = spec
        return spec

    def unregister(self, node_id: str) -> None:
        self._specs.pop(node_id, None)

    def has(self, node_id: str) -> bool:
        return node_id in self._specs

    def node_ids(self) -> list[str]:
        return sorted(self._specs)

    def spec(self, node_id: str) -> NodeSpec:
        try:
            return self._specs[node_id]
        except KeyError:
            raise BTError(f"Node not recognized: {node_id}") from None

    def get(self, node_id: str) -> NodeSpec | None:
        return self._specs.get(node_id)

    def register_enum(self, name: str, value: int) -> None:
        self.enums[name] = int(value)

    def tree_nodes_model_xml(self, only_plugins: bool = True) -> str:
        """The registered node types as a Groot2 palette; built-ins left out unless `only_plugins` is
        False (Groot2 knows them already)."""
        specs = (self._specs[node_id] for node_id in self.node_ids())
        if only_plugins:
            specs = (spec for spec in specs if not spec.is_builtin)
        return treenodesmodel.build_tree_nodes_model(specs)
