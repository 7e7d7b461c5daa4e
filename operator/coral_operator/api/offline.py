"""The `offline` setting of a CoralSystem: may its robots run their last revision without the API
server (docs/offline.md)."""

from __future__ import annotations

from typing import Literal

from coral_core.wire import CamelModel


class OfflineSpec(CamelModel):
    """Offline autonomy of the system's robots."""

    mode: Literal["Off", "LastRevision"] = "Off"
    """`Off` (default): a robot that boots without the API server runs nothing of this system until
    the link is back. `LastRevision`: the robot keeps a sealed copy of the last revision it ran
    (pods, tree, parameters; images stay in its runtime) and its agent runs that copy as static pods
    when it boots cut off; the API server's pods take over once it is back, never beside the copy."""


class InstanceOffline(CamelModel):
    """What a robot's pods carry of the offline setting (only when it is on)."""

    mode: Literal["LastRevision"] = "LastRevision"
    """The robot may run its last revision offline."""
    interrupt_running_trees: bool = False
    """Copied from `rollout.interruptRunningTrees`: the hand-over to the API server's pods may stop a
    tree that is still running offline."""
