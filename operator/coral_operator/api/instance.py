"""The CoralInstance kind: one robot's share of a CoralSystem, like a ReplicaSet for a Deployment.

Built by `planning.instances` from a CoralSystem and a robot Node; its pods are planned by
`planning.pods`; its status is written by the operator (conditions, components, robot) and by the
robot's executor (`tree`, `plugins`, through the status sink).
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from coral_operator.api.base import CamelModel
from coral_operator.api.common import Condition
from coral_operator.api.components import Component, Role
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
    executors: list[Component] = Field(default_factory=list, max_length=MAX_COMPONENTS)
    """Executor components."""
    layout: Layout = "PodPerComponent"
    """One pod per component (`PodPerComponent`) or one pod for the robot (`PodPerRobot`)."""
    startup: StartupSpec = Field(default_factory=StartupSpec)
    """Ordered startup settings."""
    plugins: PluginsSpec = Field(default_factory=PluginsSpec)
    """Plugin delivery settings."""
    retiring: bool = False
    """The robot left the system's selector: stop executors, then skillsets, then drivers, then remove
    this instance."""


class RobotState(CamelModel):
    """Whether the robot's Node is reachable and Ready."""

    node_name: str | None = None
    """The robot's Node."""
    reachable: bool | None = None
    """The robot's kubelet reports in: the Node's Ready condition is True or False, not Unknown, and
    the Node carries no `node.kubernetes.io/unreachable` taint."""
    node_ready: bool | None = None
    """The Node's Ready condition is True (a reachable robot can be not Ready; its kubelet says why)."""
    last_seen: str | None = None
    """While the robot is unreachable: when its kubelet last renewed its Node Lease (RFC 3339)."""


class ComponentState(CamelModel):
    """One component's pod as last observed."""

    name: str
    """Component name."""
    role: Role
    """driver, skillset or executor."""
    pod: str | None = None
    """Pod name; empty while the component waits for its startup stage."""
    phase: str = "Waiting"
    """Pod phase, or `Waiting` before the pod exists."""
    ready: bool = False
    """The pod is Ready (or, for a transient component, Succeeded)."""
    restarts: int = 0
    """Container restarts."""
    revision: str | None = None
    """Revision the pod was built from."""


class TreeFailure(CamelModel):
    """The last failure seen in the tree."""

    path: str = ""
    """Path of the node that failed, for example `Root/Sequence/Navigate`."""
    message: str = ""
    """What failed."""
    time: str | None = None
    """When it failed (RFC 3339)."""


class NoProgress(CamelModel):
    """One node failing the same way again and again: the tree makes no progress."""

    path: str = ""
    """Path of the node that keeps failing."""
    message: str = ""
    """How it fails (its first failure's message)."""
    since: str | None = None
    """When it started failing so (RFC 3339)."""


class TreeState(CamelModel):
    """Behavior-tree status, written by the robot's executor."""

    root_status: Literal["IDLE", "RUNNING", "SUCCESS", "FAILURE", "SKIPPED"] = "IDLE"
    """Status of the root node."""
    active_path: str = ""
    """Path of the deepest RUNNING node."""
    tick_count: int = 0
    """Ticks since the executor started."""
    last_transition_time: str | None = None
    """When a node last changed status (RFC 3339)."""
    last_failure: TreeFailure | None = None
    """The last node failure."""
    no_progress: NoProgress | None = None
    """Set while one node keeps failing the same way (`tree.noProgressSeconds`)."""
    message: str = ""
    """Executor message, for example which node types are missing."""
    updated_at: str | None = None
    """When the executor wrote this (RFC 3339)."""


class PluginState(CamelModel):
    """Behaviors exported by the robot's skillsets, as the executor sees them."""

    loaded: list[str] = Field(default_factory=list)
    """Loaded plugin components."""
    missing: list[str] = Field(default_factory=list)
    """Node types the tree uses that no plugin provides."""
    conflicts: list[str] = Field(default_factory=list)
    """Name clashes and refused manifests, one sentence each."""
    degraded: list[str] = Field(default_factory=list)
    """Components whose process died under a loaded behavior."""


class CoralInstanceStatus(CamelModel):
    """Observed state of one robot."""

    observed_generation: int | None = None
    """The generation this status was computed from."""
    conditions: list[Condition] = Field(default_factory=list)
    """Ready, Reconciling, Stalled, RobotReachable, ComponentsReady, PluginsReady, LibraryDegraded,
    TreeHealthy."""
    revision: str | None = None
    """Revision every component pod runs; empty while pods of several revisions coexist."""
    robot: RobotState = Field(default_factory=RobotState)
    """Reachability of the robot."""
    components: list[ComponentState] = Field(default_factory=list)
    """One entry per component, in startup order."""
    plugins: PluginState | None = None
    """Exported behaviors, written by the executor."""
    tree: TreeState | None = None
    """Tree status, written by the executor."""
