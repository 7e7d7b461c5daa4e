"""Test helpers: a registry with StatusQueue-style scripted leaves and a one-call tree builder."""

from __future__ import annotations

import coral_core.bt as bt
from coral_core.bt.leaves import StatefulAction

S, F, R, K = bt.Status.SUCCESS, bt.Status.FAILURE, bt.Status.RUNNING, bt.Status.SKIPPED


class Queues:
    def __init__(self, scripts: dict[str, list[bt.Status]]) -> None:
        self.scripts = {k: list(v) for k, v in scripts.items()}
        self.calls: dict[str, int] = {}
        self.halted: list[str] = []

    def next(self, name: str) -> bt.Status:
        self.calls[name] = self.calls.get(name, 0) + 1
        seq = self.scripts[name]
        return seq.pop(0) if len(seq) > 1 else seq[0]


def make_tree(
    body: str,
    scripts: dict[str, list[bt.Status]] | None = None,
    *,
    trees: str = "",
    blackboard: dict | None = None,
) -> tuple[bt.Tree, Queues]:
    queues = Queues(scripts or {})
    registry = bt.NodeRegistry.with_builtins()

    class Q(StatefulAction):
        def on_start(self) -> bt.Status:
            return queues.next(self.name)

        def on_running(self) -> bt.Status:
            return queues.next(self.name)

        def on_halted(self) -> None:
            queues.halted.append(self.name)

    registry.register("Q", Q)
    xml = (
        f'<root BTCPP_format="4" main_tree_to_execute="Main"><BehaviorTree ID="Main">{body}'
        f"</BehaviorTree>{trees}</root>"
    )
    return bt.build_tree(bt.load_tree_text(xml, registry), registry, blackboard=blackboard), queues
