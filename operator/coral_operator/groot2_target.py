"""Which pod and port serve a robot's live tree: the lookup behind `coral groot2 SYSTEM ROBOT` and
`coral tree watch SYSTEM ROBOT` (docs/groot2.md).

A robot's CoralInstance names its executors' pods and, for executors with `groot2` set, the port
their publisher listens on inside the pod (`status.components[].groot2Port`). `find_target` reads
that from the instances of one system; `check_running` refuses a pod that cannot be forwarded to
yet. Both are pure and raise `TargetError` with a sentence a user can act on; `read_target` is
the thin part that asks the API server.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from coral_core import names
from kubernetes import client as k8s
from kubernetes.client.exceptions import ApiException

from coral_operator.api import keys
from coral_operator.planning import naming

ENABLE_HINT = (
    "enable it with `groot2: {port: 1667}` on an executor in spec.executors "
    "(`allowHooks: true` for breakpoints, where the operator's policy allows them)"
)


class TargetError(Exception):
    """The robot's live tree cannot be reached; the message says why and what to do."""


@dataclass(frozen=True)
class Target:
    """One executor's Groot2 publisher: its pod and the port it listens on there (and the next)."""

    namespace: str
    pod: str
    port: int
    executor: str


def _robot_of(instance: Mapping[str, Any]) -> str:
    return str((instance.get("spec") or {}).get("robot", ""))


def find_target(
    *,
    system: str,
    robot: str,
    namespace: str,
    instances: Sequence[Mapping[str, Any]],
    executor: str | None = None,
) -> Target:
    """The publisher of `robot` among the system's `instances` (CoralInstance bodies).

    Raises:
        TargetError: no instance for the robot, no executor with groot2 (or not the one named, or
            several and none named), or its pod not created yet.
    """
    instance = next((i for i in instances if _robot_of(i) == robot), None)
    if instance is None:
        robots = ", ".join(sorted(_robot_of(i) for i in instances)) or "none yet"
        raise TargetError(
            f"robot {robot} is not matched by coralsystem/{system} in namespace {namespace} "
            f"(its robots: {robots})"
        )
    components = (instance.get("status") or {}).get(keys.INSTANCE_STATUS.components) or []
    served = [c for c in components if c.get(keys.COMPONENT.groot2_port)]
    declared = [e for e in (instance.get("spec") or {}).get("executors", []) if e.get("groot2")]
    if not served:
        if declared:
            raise TargetError(
                f"the CoralInstance of robot {robot} does not report its executor's pod yet; try again "
                "once the operator started it"
            )
        raise TargetError(f"coralsystem/{system} does not publish its trees over Groot2: {ENABLE_HINT}")
    if executor is not None:
        chosen = [c for c in served if c.get(keys.COMPONENT.name) == executor]
        if not chosen:
            listed = ", ".join(c[keys.COMPONENT.name] for c in served)
            raise TargetError(
                f"executor {executor} of coralsystem/{system} has no groot2 (those with it: {listed})"
            )
    elif len(served) > 1:
        listed = ", ".join(c[keys.COMPONENT.name] for c in served)
        raise TargetError(
            f"coralsystem/{system} has several executors with groot2 ({listed}): name one with --executor"
        )
    else:
        chosen = served
    entry = chosen[0]
    pod = entry.get(keys.COMPONENT.pod)
    if not pod:
        raise TargetError(
            f"the executor {entry[keys.COMPONENT.name]} of robot {robot} has no pod yet "
            f"({entry.get(keys.COMPONENT.phase, 'Waiting')}: it starts once the skillsets are ready)"
        )
    return Target(
        namespace=namespace,
        pod=pod,
        port=int(entry[keys.COMPONENT.groot2_port]),
        executor=entry[keys.COMPONENT.name],
    )


def check_running(target: Target, phase: str | None, running_containers: Mapping[str, bool]) -> None:
    """Refuse a pod whose executor is not running.

    Raises:
        TargetError: the pod is gone, not Running yet, or its executor container is not running.
    """
    if phase is None:
        raise TargetError(f"pod {target.pod} of executor {target.executor} no longer exists; try again")
    if phase != "Running" or not running_containers.get(target.executor, False):
        state = phase if phase != "Running" else "its container not running"
        raise TargetError(f"the executor's pod {target.pod} is not running yet ({state}); try again shortly")


def read_target(
    api_client: k8s.ApiClient, namespace: str, system: str, robot: str, executor: str | None
) -> Target:
    """Ask the API server where the robot's publisher is (see `find_target`, `check_running`).

    Raises:
        TargetError: as `find_target` and `check_running`, or the system does not exist.
    """
    custom = k8s.CustomObjectsApi(api_client)
    try:
        custom.get_namespaced_custom_object(
            names.GROUP, names.VERSION, namespace, names.SYSTEM_PLURAL, system
        )
    except ApiException as error:
        if error.status == 404:
            raise TargetError(f"coralsystem/{system} not found in namespace {namespace}") from error
        raise
    listed = custom.list_namespaced_custom_object(
        names.GROUP,
        names.VERSION,
        namespace,
        names.INSTANCE_PLURAL,
        label_selector=f"{names.LABEL_SYSTEM}={naming.label_value(system)}",
    )
    # A long name's label value is shortened, so the spec says whose instance it is.
    instances = [i for i in listed.get("items", []) if i.get("spec", {}).get("system") == system]
    target = find_target(
        system=system, robot=robot, namespace=namespace, instances=instances, executor=executor
    )
    try:
        pod = k8s.CoreV1Api(api_client).read_namespaced_pod(target.pod, namespace)
    except ApiException as error:
        if error.status != 404:
            raise
        check_running(target, None, {})
    running = {
        s.name: s.state is not None and s.state.running is not None
        for s in pod.status.container_statuses or []
    }
    check_running(target, pod.status.phase, running)
    return target
