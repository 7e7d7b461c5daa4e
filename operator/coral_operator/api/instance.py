"""The CoralInstance kind: one robot's share of a CoralSystem, like a ReplicaSet for a Deployment.

Built by `planning.instances` from a CoralSystem and a robot Node; its pods are planned by
`planning.pods`. Its status model is part of the robot/operator contract and lives in
`coral_core.instance_status`.
"""

from __future__ import annotations

from coral_core.halt import HaltRequest
from coral_core.wire import CamelModel
from pydantic import Field

from coral_operator.api.components import Component, ExecutorComponent
from coral_operator.api.offline import InstanceOffline
from coral_operator.api.system import MAX_COMPONENTS, Layout, PluginsSpec, RosSpec, StartupSpec


class ConfigRef(CamelModel):
    """A ConfigMap the operator made from a validated file; immutable, named by content hash."""

    config_map: str = Field(min_length=1, max_length=253)
    """ConfigMap name."""


class InstanceTree(ConfigRef):
    """The validated tree this robot runs."""

    main_tree_id: str | None = None
    """ID of the tree to run."""
    tick_rate_hz: float = 10.0
    """How often the executor ticks the tree."""
    no_progress_seconds: int | None = Field(default=None, ge=0, le=86400)
    """How long one node may fail the same way before the tree counts as making no progress."""


class CoralInstanceSpec(CamelModel):
    """What one robot runs: a frozen copy of one revision of its CoralSystem."""

    system: str = Field(min_length=1, max_length=253)
    """Name of the owning CoralSystem."""
    robot: str = Field(min_length=1, max_length=63)
    """Robot name (the Node's `coral.dev/robot` label)."""
    node_name: str = Field(min_length=1, max_length=253)
    """The robot's Node; every pod is pinned to it."""
    revision: str = Field(min_length=1, max_length=64)
    """Hash of the system revision this instance runs; rollouts move instances between revisions."""
    config_hash: str | None = Field(default=None, max_length=64)
    """Hash of this robot's effective configuration (the revision with the overrides that match
    the robot resolved): robots with equal hashes run the same thing; a new revision that leaves it
    unchanged moves the robot without restarting anything."""
    ros: RosSpec = Field(default_factory=RosSpec)
    """ROS 2 settings."""
    parameters: ConfigRef
    """The validated ROS parameters."""
    tree: InstanceTree
    """The validated behavior tree."""
    drivers: list[Component] = Field(default_factory=list, max_length=MAX_COMPONENTS)
    """Driver components."""
    skillsets: list[Component] = Field(default_factory=list, max_length=MAX_COMPONENTS)
    """Skillset components."""
    executors: list[ExecutorComponent] = Field(default_factory=list, max_length=MAX_COMPONENTS)
    """Executor components."""
    layout: Layout = "PodPerComponent"
    """One pod per component (`PodPerComponent`) or one pod for the robot (`PodPerRobot`)."""
    startup: StartupSpec = Field(default_factory=StartupSpec)
    """Ordered startup settings."""
    plugins: PluginsSpec = Field(default_factory=PluginsSpec)
    """Plugin delivery settings."""
    halt: HaltRequest | None = None
    """Set while the system halts this robot (`CoralSystem.spec.halt`): the executor halts its tree
    and ticks it no more. Not part of the revision: pods do not change."""
    offline: InstanceOffline | None = None
    """Set when the robot may run this revision offline (the system's `offline.mode` is not `Off`)."""
    retiring: bool = False
    """The robot left the system's selector: stop executors, then skillsets, then drivers, then remove
    this instance."""
