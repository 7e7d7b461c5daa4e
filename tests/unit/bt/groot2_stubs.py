"""Test helpers for the Groot2 publisher: publish a tree on a free port pair, a 100-node tree."""

from __future__ import annotations

import random
from typing import Any

import coral_core.bt as bt
import zmq
from coral_core.bt.groot2 import Groot2Publisher


def publish(tree: bt.Tree, **options: Any) -> Groot2Publisher:
    """A publisher on the first free port pair from a random even port (tests run side by side)."""
    port = random.randrange(30000, 40000, 2)
    for _ in range(200):
        try:
            return Groot2Publisher(tree, port, **options)
        except zmq.ZMQError:
            port += 2
    raise RuntimeError("no free port pair for a Groot2 publisher")


def hundred_node_tree() -> bt.Tree:
    """99 AlwaysSuccess leaves in 9 Sequences of 11 under one root Sequence (100 nodes with the
    root): every node runs on every tick."""
    groups = "".join("<Sequence>" + "<AlwaysSuccess/>" * 10 + "</Sequence>" for _ in range(9))
    xml = (
        '<root BTCPP_format="4" main_tree_to_execute="Main"><BehaviorTree ID="Main">'
        f"<Sequence>{groups}</Sequence></BehaviorTree></root>"
    )
    registry = bt.NodeRegistry.with_builtins()
    return bt.build_tree(bt.load_tree_text(xml, registry), registry)
