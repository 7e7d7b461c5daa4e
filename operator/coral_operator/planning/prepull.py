"""Images before the wave: which robots have the target revision's images, and whether a wave may start.

With `spec.rollout.prePull`, every online robot that is to move gets a pre-pull pod from the
system pass: one pod pinned to its Node whose containers are the target revision's images running
a no-op command, so the robot's own kubelet and runtime pull them, with their credentials, their
back-off and their messages (docs/rollouts.md, "Images before the wave"). The pod is observed
through the pod watch the operator already has, so nothing is watched when the feature is off.

Pure: the reconciler reads each robot's pods from the index, `planning.pull_state` says where its
pull stands, `check_pre_pull` says who may move and what `status.rollout.prePull` reads, and
`plan_pulls` says which pre-pull pods to create and delete.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from datetime import datetime, timedelta
from typing import Any

from coral_core import names
from coral_core.names import API_VERSION

from coral_operator.api.rollout import MAX_NAMED, PrePullStatus, PullFailure
from coral_operator.api.system import PrePullSpec
from coral_operator.planning import naming
from coral_operator.planning.observed import ObservedPod
from coral_operator.planning.pods import TOLERATIONS
from coral_operator.planning.pull_state import PULL_COMMAND, PULL_ROLE, Pull, PullState
from coral_operator.planning.rollout_checks import parse_stamp, stamp


@dataclass(frozen=True)
class PullingRobot:
    """A robot the rollout still has to move, as the pre-pull sees it."""

    robot: str
    online: bool
    pull: Pull


@dataclass(frozen=True)
class PullGate:
    """The pre-pull's decision for one pass."""

    may_move: frozenset[str]
    """Robots whose images are present; only these may be moved."""
    held: bool
    """`BeforeRollout` and not yet released: nobody moves."""
    status: PrePullStatus
    reason: str
    wake_at: datetime | None = None
    """The deadline, while robots still pull: decide again then even if no pod changes."""


def check_pre_pull(
    *,
    spec: PrePullSpec,
    robots: Sequence[PullingRobot],
    target: str,
    previous: PrePullStatus | None,
    now: datetime,
) -> PullGate:
    """Who may move to `target` this pass, and the pre-pull's status.

    Offline robots are not waited for here: `offlineRobots` already decides whether the rollout
    waits for them, and one that comes back pulls before it moves like any other.
    """
    same = previous is not None and previous.revision == target
    started = parse_stamp(previous.started) if same and previous is not None else None
    started = started or now
    deadline = started + timedelta(seconds=spec.deadline_seconds)
    late = now >= deadline
    online = [r for r in robots if r.online]
    pulled = [r for r in online if r.pull.state == PullState.PULLED]
    failed = [
        PullFailure(robot=r.robot, message=r.pull.message)
        if r.pull.state == PullState.FAILED
        else PullFailure(robot=r.robot, message=f"Images not on the robot after {spec.deadline_seconds} s.")
        for r in online
        if r.pull.state == PullState.FAILED or (late and r.pull.state != PullState.PULLED)
    ]
    pulling = len(online) - len(pulled) - len(failed)
    released = bool(same and previous is not None and previous.released) or pulling == 0 or late
    if spec.when == "BeforeEachWave":
        reason = "EachRobotWhenPulled"
    elif released:
        reason = "Released"
    else:
        reason = "WaitingForImages"
    status = PrePullStatus(
        revision=target,
        robots=len(online),
        pulled=len(pulled),
        pulling=pulling,
        failed=len(failed),
        started=stamp(started),
        released=released,
        failures=sorted(failed, key=lambda f: f.robot)[:MAX_NAMED],
    )
    return PullGate(
        may_move=frozenset(r.robot for r in pulled),
        held=spec.when == "BeforeRollout" and not released,
        status=status,
        reason=reason,
        wake_at=deadline if pulling and not late else None,
    )


@dataclass
class PullWrites:
    """The pre-pull pods to create and delete in one pass."""

    create: list[dict[str, Any]] = field(default_factory=list)
    delete: list[str] = field(default_factory=list)


@dataclass(frozen=True)
class PullTarget:
    """A robot's instance and the images it is to pull (empty: it needs none)."""

    instance: str
    instance_uid: str
    node_name: str
    robot: str
    images: tuple[str, ...]


def plan_pulls(
    *,
    system: str,
    namespace: str,
    target: str,
    wanted: Sequence[PullTarget],
    pods: Mapping[str, Sequence[ObservedPod]],
) -> PullWrites:
    """Create a pre-pull pod where a robot to move has none for `target`; delete every other one.

    `pods` maps instance name to its pods; `wanted` lists the robots that must pull now.
    """
    writes = PullWrites()
    wanted_by_instance = {w.instance: w for w in wanted if w.images}
    for instance, observed in pods.items():
        for pod in observed:
            if pod.role != PULL_ROLE or pod.deleting:
                continue
            if instance not in wanted_by_instance or pod.revision != target:
                writes.delete.append(pod.name)
    for instance, want in sorted(wanted_by_instance.items()):
        have = [p for p in pods.get(instance, ()) if p.role == PULL_ROLE and p.revision == target]
        if not have:
            writes.create.append(build_pull_pod(system=system, namespace=namespace, target=target, want=want))
    return writes


def build_pull_pod(*, system: str, namespace: str, target: str, want: PullTarget) -> dict[str, Any]:
    """A pod that makes the robot's kubelet pull `want.images` and then ends."""
    labels = {
        names.LABEL_MANAGED_BY: names.MANAGER,
        names.LABEL_SYSTEM: naming.label_value(system),
        names.LABEL_ROBOT: want.robot,
        names.LABEL_INSTANCE: want.instance,
        names.LABEL_ROLE: PULL_ROLE,
        names.LABEL_COMPONENT: PULL_ROLE,
        names.LABEL_REVISION: target,
    }
    containers = [
        {
            "name": f"image-{index}",
            "image": image,
            "imagePullPolicy": "IfNotPresent",
            "command": list(PULL_COMMAND),
            "resources": {"requests": {"cpu": "1m", "memory": "4Mi"}, "limits": {"memory": "32Mi"}},
        }
        for index, image in enumerate(want.images)
    ]
    return {
        "apiVersion": "v1",
        "kind": "Pod",
        "metadata": {
            "name": naming.pod_name(want.instance, PULL_ROLE, target),
            "namespace": namespace,
            "labels": labels,
            "ownerReferences": [
                naming.owner_reference(API_VERSION, names.INSTANCE_KIND, want.instance, want.instance_uid)
            ],
        },
        "spec": {
            "nodeName": want.node_name,
            "restartPolicy": "Never",
            "automountServiceAccountToken": False,
            "enableServiceLinks": False,
            "terminationGracePeriodSeconds": 0,
            # A robot offline or not Ready keeps its pods, as its components' pods do.
            "tolerations": [dict(t) for t in TOLERATIONS],
            "containers": containers,
        },
    }


def revision_images(template: Mapping[str, Any]) -> tuple[str, ...]:
    """The distinct images of an instance template's components, in order."""
    seen: dict[str, None] = {}
    for group in ("drivers", "skillsets", "executors"):
        for component in template.get(group) or []:
            if component.get("image"):
                seen.setdefault(component["image"], None)
    return tuple(seen)
