"""One CoralInstance pass as a pure decision: which pods to create, delete, relabel or patch.

`plan_instance` parses the instance's spec, and either plans the robot's ordered startup
(`planning.startup`), or, for an instance whose robot left its system, the reverse-order shutdown.
It writes nothing: the reconciler (`reconcile.instances`) applies the plan through `kube` and
computes status from what it observes afterwards (docs/architecture.md).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from datetime import datetime
from typing import Any

from coral_core import names
from pydantic import ValidationError

from coral_operator.api.instance import CoralInstanceSpec
from coral_operator.planning import naming, pods, startup
from coral_operator.planning.observed import InstanceRecord, ObservedPod, RobotNode


@dataclass
class InstancePlan:
    """The writes of one instance pass; exactly one of `invalid`, `retire` and `startup` is set."""

    spec: CoralInstanceSpec | None = None
    invalid: str | None = None
    """Why the spec is invalid (a sentence naming the fields); nothing is written but status."""
    retire: bool = False
    """The robot left the system: stop its pods in reverse order (`stop`), then the instance."""
    stop: list[str] = field(default_factory=list)
    delete_instance: bool = False
    """Nothing is left to stop in order (or no kubelet could): remove the instance now."""
    startup: startup.StartupPlan | None = None
    desired: list[dict[str, Any]] = field(default_factory=list)
    transient: set[str] = field(default_factory=set)


def parse_instance_spec(record: InstanceRecord) -> CoralInstanceSpec | str:
    """The parsed spec, or a sentence naming every invalid field."""
    try:
        return CoralInstanceSpec.model_validate(record.spec)
    except ValidationError as error:
        return "; ".join(f"spec.{'.'.join(map(str, e['loc']))}: {e['msg']}" for e in error.errors())


def build_desired_pods(
    record: InstanceRecord, spec: CoralInstanceSpec, settings: pods.PodSettings | None = None
) -> list[dict[str, Any]]:
    """The pods the instance's spec asks for, in startup order.

    Raises:
        pods.HostPathRefused: a host path lies outside every folder the namespace may mount.
    """
    return pods.build_pods(
        spec=spec,
        instance=record.name,
        namespace=record.namespace,
        instance_uid=record.uid,
        settings=settings,
    )


def plan_instance(
    *,
    record: InstanceRecord,
    spec: CoralInstanceSpec | str,
    desired: list[dict[str, Any]],
    node: RobotNode | None,
    observed: list[ObservedPod],
    now: datetime,
) -> InstancePlan:
    """Decide one pass of a CoralInstance.

    Args:
        record: the instance as observed.
        spec: `parse_instance_spec(record)`.
        desired: `build_desired_pods(record, spec)` (the reconciler keeps it per generation).
        node: the robot's Node, None when it does not exist.
        observed: the instance's pods, one record per component.
        now: the clock.
    """
    if isinstance(spec, str):
        return InstancePlan(invalid=spec)
    if spec.retiring:
        if not observed or node is None or not node.ready:
            # Nothing left to stop, or no kubelet to stop it: garbage collection takes the rest.
            return InstancePlan(spec=spec, retire=True, delete_instance=True)
        return InstancePlan(spec=spec, retire=True, stop=startup.plan_shutdown(observed))
    transient = {c.name for c in spec.drivers + spec.skillsets + spec.executors if c.transient}
    plan = startup.plan_startup(
        desired=desired,
        observed=observed,
        transient=transient,
        startup=spec.startup,
        now=now,
        robot_since=node.ready_since if node is not None else None,
    )
    return InstancePlan(spec=spec, startup=plan, desired=desired, transient=transient)


def refusal_key(manifest: dict[str, Any]) -> str:
    """What a refusal of this pod is reported under: its component, or the whole robot's pod."""
    return manifest["metadata"]["labels"].get(names.LABEL_COMPONENT, naming.ROBOT_POD)
