"""Plain records of what the operator observed in the cluster, decoupled from API objects.

`kube.observing` builds them from API bodies; the planners and status builders read them.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from datetime import datetime
from typing import Any, ClassVar

from coral_core import names

from coral_operator.planning import naming

ROBOT_SPEC_FIELDS = ("robot", "nodeName", "revision", "halt")
"""The fields of a CoralInstance spec that differ between the robots of one system at one revision
(`halt` only some robots may carry)."""


@dataclass(frozen=True)
class RobotNode:
    """A Node carrying the `coral.dev/robot` label."""

    node_name: str
    robot: str
    labels: dict[str, str]
    ready: bool
    """The Node's Ready condition is True: its kubelet can run pods."""
    last_seen: datetime | None = None
    """The robot's last heartbeat: its Node Lease's renewTime when read, else the Ready heartbeat."""
    reachable: bool = True
    """The kubelet reports in: Ready is True or False (not Unknown) and no `unreachable` taint.
    A robot can be reachable and not Ready (its kubelet says why)."""
    ready_message: str = ""
    """The Ready condition's message, which says why a reachable robot is not Ready."""
    ready_since: datetime | None = None
    """When the Node last turned Ready (its Ready condition's transition), if it is Ready: a robot
    back from a reboot or an outage starts its components over from then."""
    annotations: dict[str, str] = field(default_factory=dict)
    """The Node's own annotations (`kube.observing.robot_annotations`), which overrides may
    substitute (`${robot.annotations['KEY']}`)."""


@dataclass(frozen=True)
class ObservedPod:
    """A component pod as last seen; for a robot pod (`PodPerRobot`), one component's container in
    it, so planning and status read both layouts alike."""

    name: str
    component: str
    role: str
    revision: str
    pod_hash: str
    phase: str
    ready: bool
    created: datetime | None
    deleting: bool = False
    unready_since: datetime | None = None
    """When the pod last stopped being Ready (its Ready condition's transition), if it is not Ready."""
    settled: bool = False
    """The component has been ready since its container last started, so it is not starting up: an
    unready settled component (a readiness probe missing mid-mission, a transient run ending) is
    not held to the startup health timeout."""
    restarts: int = 0
    crash_looping: bool = False
    image_problem: str | None = None
    """Why the kubelet cannot pull or start an image, with its message (`ErrImagePull: ...`)."""
    container_refused: str | None = None
    """Why the kubelet refuses to create one of the pod's containers, init containers included, with
    its message (`CreateContainerConfigError: failed to prepare subPath ...`): a host path's subPath
    that leads out of its folder, a missing ConfigMap."""
    unschedulable: str | None = None
    """Why the robot cannot run the pod (the scheduler's or the kubelet's admission message)."""
    shape_hash: str = ""
    """A robot pod's hash without images (`coral_core.names.ANNOTATION_SHAPE_HASH`); empty for component
    pods."""
    images: tuple[tuple[str, str], ...] = ()
    """A robot pod's (container, image) pairs, so an image-only change can be patched in place."""


@dataclass(frozen=True)
class ObservedInstance:
    """A CoralInstance as the system sees it."""

    name: str
    robot: str
    spec: dict
    revision: str
    ready: bool = False
    reachable: bool | None = None
    node_ready: bool | None = None
    """The robot's Node is Ready (None before the instance's first status)."""
    root_status: str | None = None
    labels: dict[str, str] = field(default_factory=dict)
    stalled: bool = False
    """The instance is Stalled at its current generation (a component failed, or startup timed out)."""
    uid: str = ""
    generation: int | None = None
    resource_version: str | None = None
    """The object's version as observed: a status this process wrote later is read instead."""
    controller_uid: str = ""
    """The uid of the instance's controller owner; a system takes over an instance at one of its
    names that it does not control (`planning.instances.plan_instances`)."""

    @functools.cached_property
    def shared_spec_key(self) -> str:
        """The hash of the spec but its `ROBOT_SPEC_FIELDS`: one value for every robot at one
        revision. Kept with the observed object (one per watch event), so a system pass over a
        thousand robots compares a hash per robot instead of a whole spec."""
        return shared_spec_key(self.spec)


def shared_spec_key(spec: dict[str, Any]) -> str:
    """See `ObservedInstance.shared_spec_key`."""
    return naming.content_hash(
        {k: _numbers_as_stored(v) for k, v in spec.items() if k not in ROBOT_SPEC_FIELDS}, length=16
    )


def _numbers_as_stored(value: Any) -> Any:
    # The API server stores 10.0 as 10; equal values must give equal keys.
    if isinstance(value, float) and value.is_integer():
        return int(value)
    if isinstance(value, dict):
        return {k: _numbers_as_stored(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_numbers_as_stored(v) for v in value]
    return value


@dataclass(frozen=True)
class _OwnRecord:
    """What a pass reads of its own object (the fields both kinds have)."""

    KIND: ClassVar[str]
    name: str
    namespace: str
    uid: str
    generation: int | None
    spec: dict[str, Any]
    status: dict[str, Any]

    @property
    def reference(self) -> dict[str, Any]:
        """Enough of a body for an Event to name its object."""
        return {
            "apiVersion": names.API_VERSION,
            "kind": self.KIND,
            "metadata": {"name": self.name, "namespace": self.namespace, "uid": self.uid},
        }


@dataclass(frozen=True)
class InstanceRecord(_OwnRecord):
    """What a CoralInstance pass reads of its own object."""

    KIND: ClassVar[str] = names.INSTANCE_KIND
    resource_version: str | None = None
    owners: tuple[dict[str, Any], ...] = ()
    """`metadata.ownerReferences`: whether the instance is its system's (`planning.provenance`)."""


@dataclass(frozen=True)
class SystemRecord(_OwnRecord):
    """What a CoralSystem pass reads of its own object."""

    KIND: ClassVar[str] = names.SYSTEM_KIND
    annotations: dict[str, str] = field(default_factory=dict)
    resource_version: str | None = None
    created: str = ""
    """The creation timestamp (RFC 3339), which orders a namespace's systems for its budget."""
    spec_bytes: int = 0
    """The spec's size as JSON (`planning.budgets`), measured once per watch event."""
    share_bytes: int = 0
    """What one robot's copy of the spec takes (`planning.budgets.robot_share_bytes`)."""
    files_left_out: bool = False
    """The spec's inline files were left out of this record (`kube.observing.system_record`): a
    pass reads the system from the API for them."""
