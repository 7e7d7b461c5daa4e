"""The CoralSystem kind: what Coral system runs on which robots (docs/architecture.md).

Parsed by the system reconciler (`reconcile.systems`), turned into CoralInstances by
`planning.instances`, rendered into the CRD by `api.crdgen`, written by `coral convert`.
"""

from __future__ import annotations

import functools
import math
import re
from dataclasses import dataclass
from typing import Annotated, Literal

from coral_core.halt import HaltRequest
from coral_core.limits import MAX_TICK_RATE_HZ
from coral_core.wire import CamelModel, Condition
from pydantic import Field, field_validator, model_validator

from coral_operator.api.common import ConfigMapKeyRef, LabelSelector
from coral_operator.api.components import Component, ExecutorComponent
from coral_operator.api.offline import OfflineSpec
from coral_operator.api.overrides import (
    MAX_OVERRIDES,
    OVERRIDE_NAMES_UNIQUE,
    OVERRIDE_SELECTS,
    Override,
    check_overrides,
)
from coral_operator.api.rollout import RolloutStatus

MAX_COMPONENTS = 32
# Inline files are capped well below etcd's 1.5 MiB request limit, so an object carrying them (and
# `kubectl apply`'s copy of them) is refused at admission with the field's name, never by etcd.
MAX_INLINE_BYTES = 256 * 1024
MAX_TREE_FILES = 16
MAX_TREE_FILE_BYTES = 32 * 1024
TREE_FILE_NAME = r"^[-_a-zA-Z0-9][-._a-zA-Z0-9]{0,62}$"
# The names the tree and the parameters have in the executor's config folder.
RESERVED_FILE_NAMES = ("tree.xml", "params.yaml")
MAX_UNAVAILABLE = r"^((100|[1-9]?[0-9])%|[0-9]+)$"

ROBOTS_NOT_EMPTY = "robots must select with at least one label or expression"
SOURCE_EXACTLY_ONE = "set exactly one of inline or configMapRef"
PRIVILEGED_DRIVERS_ONLY = "privileged is allowed only on drivers"
UNIQUE_NAMES = "component names must be unique across drivers, skillsets and executors"
NEEDS_EXECUTOR = "at least one executor is required"
ROBOT_POD_BLOCKS = (
    "startup.onTimeout Proceed needs layout PodPerComponent: in one pod the kubelet starts a sidecar's "
    "successors only once its startup probe passed"
)
DOMAIN_RANGE = "ros.domainId must be between 0 and 232"
TREE_FILE_NAMES = (
    "tree.files names must be file names (letters, digits, '-', '_', '.'; at most 63) "
    "other than tree.xml and params.yaml"
)
MAX_UNAVAILABLE_SYNTAX = "rollout.maxUnavailable must be a count of at least 0 or a percentage like '10%'"
MAX_UNAVAILABLE_FIELD = "spec.rollout.maxUnavailable"
GROOT2_PORTS_APART = (
    "executors' groot2 ports must be at least 2 apart: each publisher uses its port and the next, and "
    "executors of one robot share its loopback"
)

METRICS_PORTS_DIFFER = "executors' metrics ports must differ: executors of one robot may share its network"


def _cel(rule: str, message: str, field_path: str | None = None) -> dict[str, str]:
    entry = {"rule": rule, "message": message}
    if field_path:
        entry["fieldPath"] = field_path
    return entry


class RosSpec(CamelModel):
    """ROS 2 settings shared by every component of the system."""

    model_config = CamelModel.model_config | {
        "json_schema_extra": {
            "x-kubernetes-validations": [
                _cel("self.domainId >= 0 && self.domainId <= 232", DOMAIN_RANGE, ".domainId")
            ]
        }
    }

    domain_id: int = 0
    """ROS_DOMAIN_ID of every component (0 to 232; 0 to 101 is safe on every Linux host)."""
    distro: str = Field(default="jazzy", max_length=32)
    """ROS 2 distribution the components are built for; mismatched plugins are refused."""
    rmw_implementation: str = Field(default="rmw_fastrtps_cpp", max_length=64)
    """RMW_IMPLEMENTATION of every component."""
    localhost_only: bool = False
    """Keep DDS discovery on the robot (ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST)."""
    network: Literal["Host", "Pod"] = "Host"
    """`Host` (default, like Coral's compose files): host network and host IPC, so DDS works
    between components and robots. `Pod`: the pod network."""

    @model_validator(mode="after")
    def _domain_in_range(self) -> RosSpec:
        if not 0 <= self.domain_id <= 232:
            raise ValueError(DOMAIN_RANGE)
        return self


class SourceSpec(CamelModel):
    """A file given inline or by a ConfigMap key; exactly one of the two."""

    model_config = CamelModel.model_config | {
        "json_schema_extra": {
            "x-kubernetes-validations": [
                _cel("has(self.inline) != has(self.configMapRef)", SOURCE_EXACTLY_ONE)
            ]
        }
    }

    inline: str | None = Field(default=None, max_length=MAX_INLINE_BYTES)
    """The file's content (at most 256 KiB; larger files belong in a ConfigMap)."""
    config_map_ref: ConfigMapKeyRef | None = None
    """A ConfigMap key holding the file's content."""

    @model_validator(mode="after")
    def _exactly_one(self) -> SourceSpec:
        if (self.inline is None) == (self.config_map_ref is None):
            raise ValueError(SOURCE_EXACTLY_ONE)
        return self


class TreeSpec(SourceSpec):
    """The behavior tree: BT.CPP v4 XML, inline or from a ConfigMap."""

    model_config = SourceSpec.model_config | {
        "json_schema_extra": {
            "x-kubernetes-validations": [
                _cel("has(self.inline) != has(self.configMapRef)", SOURCE_EXACTLY_ONE),
                _cel(
                    f"!has(self.files) || self.files.all(k, k.matches('{TREE_FILE_NAME}') "
                    "&& !(k in ['tree.xml', 'params.yaml']))",
                    TREE_FILE_NAMES,
                    ".files",
                ),
            ]
        }
    }

    files: dict[str, Annotated[str, Field(max_length=MAX_TREE_FILE_BYTES)]] = Field(
        default_factory=dict, max_length=MAX_TREE_FILES
    )
    """Further XML files the tree `<include>`s, by file name (at most 16 of 32 KiB each). Includes
    resolve only among these: `<include path="nav.xml"/>` reads `files["nav.xml"]`. The robots get
    them beside the tree."""

    @field_validator("files")
    @classmethod
    def _file_names(cls, files: dict[str, str]) -> dict[str, str]:
        for name in files:
            if not re.fullmatch(TREE_FILE_NAME, name) or name in RESERVED_FILE_NAMES:
                raise ValueError(f"{name!r}: {TREE_FILE_NAMES}")
        return files

    main_tree_id: str | None = Field(default=None, max_length=253)
    """ID of the tree to run; the document's `main_tree_to_execute` when omitted."""
    tick_rate_hz: float = Field(default=10.0, gt=0, le=MAX_TICK_RATE_HZ)
    """How often the executor ticks the tree, and the most it ticks it: a wake-up (a service's
    answer, a timer) ticks at once when a period has passed since the last tick."""
    no_progress_seconds: int | None = Field(default=None, ge=0, le=86400)
    """How long one node may fail the same way, again and again, before the robot reports that its
    tree makes no progress (`TreeHealthy=False`, reason `NoProgress`, so it is not Ready); 0 never
    reports it. Default: 60."""


class StartupSpec(CamelModel):
    """Ordered startup: drivers, then skillsets, then executors, each stage gated on readiness."""

    health_timeout_seconds: int = Field(default=120, ge=1, le=86400)
    """How long a stage may wait for the previous one to become ready."""
    on_timeout: Literal["Block", "Proceed"] = "Block"
    """`Block`: keep waiting and say so in the `ComponentsReady` condition. `Proceed`: start the next
    stage anyway."""


Layout = Literal["PodPerComponent", "PodPerRobot"]
"""How one robot's components map onto pods (see docs/layouts.md)."""


class PluginsSpec(CamelModel):
    """How exported behaviors reach the executors."""

    delivery: Literal["HostPath"] = "HostPath"
    """`HostPath`: a per-robot shared folder, one per system (the default and only mode for now)."""
    host_path_root: str = Field(default="/var/lib/coral/plugins", pattern=r"^/", max_length=512)
    """Folder on each robot under which the operator places `<namespace>/<system>`."""
    mount_path: str = Field(default="/var/lib/coral/plugins", pattern=r"^/", max_length=512)
    """Where the plugin folder appears inside every component's container (where Coral's component
    images export to)."""


@dataclass(frozen=True)
class UnavailableBudget:
    """`spec.rollout.maxUnavailable` parsed: a count of robots, or a percentage of the matched ones."""

    count: int = 0
    percent: int | None = None
    """Set for a percentage; `count` is then unused."""

    def resolve(self, total: int) -> int:
        """The budget as a count of robots out of `total`: at least 1; a percentage rounds up, as
        for DaemonSets."""
        if self.percent is not None:
            return max(1, math.ceil(total * self.percent / 100))
        return max(1, self.count)


# Reading the spec checks the value and every rollout decision asks for its budget: a fleet's few
# values are parsed once each. `typed`, so True is not taken for the count 1.
@functools.lru_cache(maxsize=256, typed=True)
def parse_max_unavailable(value: int | str) -> UnavailableBudget:
    """The one parser of `maxUnavailable`: a count of at least 0, or a percentage from 0% to 100%.

    Raises:
        ValueError: anything else; the message names the field.
    """
    malformed = f"{MAX_UNAVAILABLE_FIELD}: expected a count or a percentage like '10%', got {value!r}"
    if isinstance(value, bool):
        raise ValueError(malformed)
    if isinstance(value, int):
        if value < 0:
            raise ValueError(f"{MAX_UNAVAILABLE_FIELD}: must be a count of at least 0, got {value}")
        return UnavailableBudget(count=value)
    if not re.fullmatch(MAX_UNAVAILABLE, value):
        raise ValueError(malformed)
    if value.endswith("%"):
        return UnavailableBudget(percent=int(value[:-1]))
    return UnavailableBudget(count=int(value))


class CanarySpec(CamelModel):
    """Robots updated first; they must stay healthy for the hold time before the rest follow."""

    robots: LabelSelector
    """Selector of the canary robots among the matched ones."""
    hold_seconds: int = Field(default=300, ge=0, le=86400)
    """How long the canaries must stay healthy."""


class PrePullSpec(CamelModel):
    """Have the new revision's images pulled on the robots before they move to it."""

    when: Literal["BeforeRollout", "BeforeEachWave"] = "BeforeRollout"
    """`BeforeRollout`: no robot moves until every online robot to move has its images (or the
    deadline passed); `BeforeEachWave`: each robot moves as soon as its own images are present."""
    deadline_seconds: int = Field(default=600, ge=10, le=86400)
    """How long pulls may take; a robot still pulling then counts as a failed pull and does not move."""


class RolloutSpec(CamelModel):
    """How a spec change spreads over the fleet.

    Every instance records the revision it runs (`spec.revision`); the rollout decides which
    instances move to the newest revision and when."""

    model_config = CamelModel.model_config | {
        "json_schema_extra": {
            "x-kubernetes-validations": [
                _cel(
                    "!has(self.maxUnavailable) || (type(self.maxUnavailable) == int "
                    "? int(self.maxUnavailable) >= 0 "
                    f": string(self.maxUnavailable).matches('{MAX_UNAVAILABLE}'))",
                    MAX_UNAVAILABLE_SYNTAX,
                    ".maxUnavailable",
                )
            ]
        }
    }

    max_unavailable: int | Annotated[str, Field(max_length=8)] = Field(default="25%")
    """How many robots may be unavailable (updating or not Ready) at once: a count, or a percentage of
    the matched robots rounded up; at least 1."""

    @field_validator("max_unavailable")
    @classmethod
    def _count_or_percent(cls, value: int | str) -> int | str:
        parse_max_unavailable(value)
        return value

    def unavailable_budget(self) -> UnavailableBudget:
        """`max_unavailable` parsed (already checked when the spec was read)."""
        return parse_max_unavailable(self.max_unavailable)

    canary: CanarySpec | None = None
    """Robots updated first, as a health check for the rest."""
    paused: bool = False
    """Stop moving robots to the new revision."""
    on_failure: Literal["Pause", "Rollback"] = "Pause"
    """What a failed health gate does."""
    interrupt_running_trees: bool = False
    """Restart a robot whose tree is mid-mission (false: wait until its tree is not running)."""
    offline_robots: Literal["Skip", "Wait", "CountUnavailable"] = "Skip"
    """How robots that are offline count during a rollout."""
    pre_pull: PrePullSpec | None = None
    """Pull the new revision's images on every robot to move before it moves (off when unset)."""


# Two executors' Groot2 publishers clash when their port pairs (N, N+1) overlap.
_GROOT2_APART = (
    "self.executors.all(a, !has(a.groot2) || self.executors.all(b, b.name == a.name || !has(b.groot2) "
    "|| b.groot2.port - a.groot2.port > 1 || a.groot2.port - b.groot2.port > 1))"
)


def groot2_ports_overlap(executors: list[ExecutorComponent]) -> bool:
    ports = sorted(e.groot2.port for e in executors if e.groot2)
    return any(later - earlier < 2 for earlier, later in zip(ports, ports[1:], strict=False))


MAX_HALTED_ROBOTS = 1000


class HaltSpec(HaltRequest):
    """Halt the missions of the system's robots: an operational stop, not a safety stop.

    Each selected robot's executor halts its tree as BT.CPP's `haltTree()` does (every running
    node halted, every status reset), after ticking `parkTree` to its end if one is named, and
    acknowledges on its CoralInstance (`Halted=True`). No pod restarts. Removing the field (or a
    robot from `robots`) makes the tree tick again from its start (`coral halt`, `coral resume`).
    """

    robots: list[Annotated[str, Field(max_length=63)]] = Field(
        default_factory=list, max_length=MAX_HALTED_ROBOTS
    )
    """Robot names (their `coral.dev/robot` label) to halt; empty halts every robot of the system."""


_METRICS_PORTS_DIFFER = (
    "self.executors.all(a, !has(a.metrics) || self.executors.all(b, b.name == a.name || !has(b.metrics) "
    "|| b.metrics.port != a.metrics.port))"
)


def metrics_ports_clash(executors: list[ExecutorComponent]) -> bool:
    ports = [e.metrics.port for e in executors if e.metrics]
    return len(ports) != len(set(ports))


_ALL_NAMES = "(self.drivers.map(c, c.name) + self.skillsets.map(c, c.name) + self.executors.map(c, c.name))"


class CoralSystemSpec(CamelModel):
    """A Coral system (the tree, the components and the ROS parameters) and the robots it runs on."""

    model_config = CamelModel.model_config | {
        "json_schema_extra": {
            "x-kubernetes-validations": [
                _cel(
                    "size(self.robots.matchLabels) > 0 || size(self.robots.matchExpressions) > 0",
                    ROBOTS_NOT_EMPTY,
                    ".robots",
                ),
                _cel(
                    "self.skillsets.all(c, !c.privileged) && self.executors.all(c, !c.privileged)",
                    PRIVILEGED_DRIVERS_ONLY,
                ),
                _cel(f"{_ALL_NAMES}.all(n, {_ALL_NAMES}.exists_one(m, m == n))", UNIQUE_NAMES),
                _cel("size(self.executors) > 0", NEEDS_EXECUTOR, ".executors"),
                _cel(_GROOT2_APART, GROOT2_PORTS_APART, ".executors"),
                _cel(_METRICS_PORTS_DIFFER, METRICS_PORTS_DIFFER, ".executors"),
                _cel(
                    "!has(self.layout) || self.layout != 'PodPerRobot' || !has(self.startup) "
                    "|| !has(self.startup.onTimeout) || self.startup.onTimeout != 'Proceed'",
                    ROBOT_POD_BLOCKS,
                    ".startup.onTimeout",
                ),
                _cel(
                    "!has(self.overrides) "
                    "|| self.overrides.all(o, self.overrides.exists_one(p, p.name == o.name))",
                    OVERRIDE_NAMES_UNIQUE,
                    ".overrides",
                ),
                _cel(
                    "!has(self.overrides) || self.overrides.all(o, size(o.robots.matchLabels) > 0 "
                    "|| size(o.robots.matchExpressions) > 0)",
                    OVERRIDE_SELECTS,
                    ".overrides",
                ),
            ]
        }
    }

    robots: LabelSelector
    """Label selector over robot Nodes (labelled `coral.dev/robot=<name>`): one robot or a fleet."""
    ros: RosSpec = Field(default_factory=RosSpec)
    """ROS 2 settings."""
    parameters: SourceSpec
    """ROS parameters YAML, inline or from a ConfigMap."""
    tree: TreeSpec
    """The behavior tree (BT.CPP v4 XML), inline or from a ConfigMap."""
    drivers: list[Component] = Field(default_factory=list, max_length=MAX_COMPONENTS)
    """Hardware (or bag player) components; started first."""
    skillsets: list[Component] = Field(default_factory=list, max_length=MAX_COMPONENTS)
    """Components that export behaviors; started when the drivers are ready."""
    executors: list[ExecutorComponent] = Field(default_factory=list, max_length=MAX_COMPONENTS)
    """Components that run the tree; started when the skillsets are ready."""
    layout: Layout = "PodPerComponent"
    """`PodPerComponent` (default): one pod per component per robot, each restarted and updated on
    its own. `PodPerRobot`: one pod per robot, drivers then skillsets as native sidecars (init
    containers with `restartPolicy: Always`, gated by startup probes), executors as its main
    containers, the plugin location an `emptyDir`; no host path needed."""
    startup: StartupSpec = Field(default_factory=StartupSpec)
    """Ordered startup settings."""
    plugins: PluginsSpec = Field(default_factory=PluginsSpec)
    """Plugin delivery settings."""
    rollout: RolloutSpec = Field(default_factory=RolloutSpec)
    """Fleet rollout settings."""
    overrides: list[Override] = Field(default_factory=list, max_length=MAX_OVERRIDES)
    """What differs per robot selector: parameters, env, images, components, tree files
    (docs/overrides.md). `coral config SYSTEM ROBOT` prints what one robot runs."""
    halt: HaltSpec | None = None
    """Halt the trees of every robot, or of the robots listed; unset, the trees run."""
    offline: OfflineSpec = Field(default_factory=OfflineSpec)
    """Whether a robot that boots without the API server runs its last revision (docs/offline.md)."""

    @model_validator(mode="after")
    def _rules(self) -> CoralSystemSpec:
        # The same rules as the CEL validations, so specs built in Python (coral convert,
        # tests) fail early with the messages the API server would give.
        if not self.robots.match_labels and not self.robots.match_expressions:
            raise ValueError(ROBOTS_NOT_EMPTY)
        if any(c.privileged for c in self.skillsets + self.executors):
            raise ValueError(PRIVILEGED_DRIVERS_ONLY)
        names = [c.name for c in self.drivers + self.skillsets + self.executors]
        if len(names) != len(set(names)):
            raise ValueError(UNIQUE_NAMES)
        if not self.executors:
            raise ValueError(NEEDS_EXECUTOR)
        if groot2_ports_overlap(self.executors):
            raise ValueError(GROOT2_PORTS_APART)
        if metrics_ports_clash(self.executors):
            raise ValueError(METRICS_PORTS_DIFFER)
        if self.layout == "PodPerRobot" and self.startup.on_timeout == "Proceed":
            raise ValueError(ROBOT_POD_BLOCKS)
        refused = check_overrides(self.overrides)
        if refused:
            raise ValueError(refused)
        return self


class RobotCounts(CamelModel):
    """How many matched robots are in which state."""

    matched: int = 0
    """Robot Nodes matching the selector."""
    ready: int = 0
    """Robots whose CoralInstance is Ready."""
    updated: int = 0
    """Robots whose CoralInstance runs the newest revision."""
    unreachable: int = 0
    """Robots whose Node is not Ready."""


class TreeCounts(CamelModel):
    """How many robots' trees are in which root state, as reported by their executors."""

    running: int = 0
    """Trees whose root is RUNNING."""
    success: int = 0
    """Trees whose root returned SUCCESS."""
    failure: int = 0
    """Trees whose root returned FAILURE."""
    idle: int = 0
    """Trees not ticking yet, or with no report."""


class CoralSystemStatus(CamelModel):
    """Observed state of a CoralSystem: conditions and counts, never a per-robot list."""

    observed_generation: int | None = None
    """The generation this status was computed from."""
    conditions: list[Condition] = Field(default_factory=list)
    """Ready, Reconciling, Stalled and RobotsReachable."""
    revision: str | None = None
    """Hash of the newest revision of the spec."""
    robots: RobotCounts = Field(default_factory=RobotCounts)
    """Robot counts."""
    trees: TreeCounts = Field(default_factory=TreeCounts)
    """Tree root states over the robots."""
    rollout: RolloutStatus | None = None
    """Progress of the fleet rollout: target revision, counts, canaries, failure, rollback."""
