"""The CoralInstance's status as it travels: the contract between the operator and the executor.

The operator writes the conditions, `robot` and `components`; the robot's executor writes `tree` and
`plugins` through its status sink (`coral.executor.kubernetes_sink`), with an identity that may
write nothing else. These models are the one shape of the tree status: the sink builds a
`TreeState` and `PluginState` and patches them (`to_patch`), and the operator reads what an
executor wrote back into them (`coral_operator.status.executor_report`). Code that handles the raw
wire dict takes the field names from `coral_core.keys`.
"""

from __future__ import annotations

from typing import Literal, get_args

from coral_core.wire import CamelModel, Condition
from pydantic import Field

Role = Literal["driver", "skillset", "executor"]
RootStatus = Literal["IDLE", "RUNNING", "SUCCESS", "FAILURE", "SKIPPED"]
"""What a tree's root can report, BT.CPP's node statuses."""
ROOT_STATUSES: tuple[str, ...] = get_args(RootStatus)


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
    groot2_port: int | None = None
    """Executors with `groot2` set: the port their Groot2 publisher listens on, on 127.0.0.1 inside
    the pod (the next one publishes breakpoints); `coral groot2 SYSTEM ROBOT` forwards both."""


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


ParkStatus = Literal["SUCCESS", "FAILURE", "TIMEOUT", "MISSING"]
"""How a park tree ended: its root's status, out of time, or not in the tree document."""
PARK_STATUSES: tuple[str, ...] = get_args(ParkStatus)


class TreeHalt(CamelModel):
    """The executor's acknowledgement of a halt: its tree is halted and no longer ticks."""

    since: str | None = None
    """When the tree was halted (RFC 3339)."""
    park_tree: str | None = None
    """The park tree ticked before halting, if the halt named one."""
    park_status: ParkStatus | None = None
    """How the park tree ended."""


class TreeState(CamelModel):
    """Behavior-tree status, written by the robot's executor."""

    root_status: RootStatus = "IDLE"
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
    halted: TreeHalt | None = None
    """Set while the tree is halted on request (`spec.halt`); cleared when it ticks again."""
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
    TreeHealthy; Halted while a halt is asked for or acknowledged."""
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
