"""Built-in coordination behaviors for executors on different robots (DESIGN section 4).

`TriggerRemote` / `WaitForRemoteTrigger` (port names as in Coral's example trees) and
`ShareValue` / `WaitForSharedValue` for data sharing, all with timeouts so a tree can fall back
when a peer is unreachable. `hub.CoordinationHub` is the ROS side; the executor creates one and
calls `register` to add the behaviors to its registry.
"""

from __future__ import annotations

from typing import Any

from coral_core import names

BEHAVIOR_IDS = names.COORDINATION_BEHAVIORS


def register(registry: Any) -> None:
    """Registers the coordination behaviors (as built-ins: plugins cannot replace them)."""
    from coral.coordination import behaviors

    for node_id in BEHAVIOR_IDS:
        registry.register(node_id, getattr(behaviors, node_id), source="coral.coordination")
