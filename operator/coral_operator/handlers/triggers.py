"""Makes a CoralSystem reconcile when something it depends on changes.

The system reconciler runs on every event of its own object (`on.event`, so kopf adds no
finalizer). What it depends on but does not own (robot Nodes, its instances, source ConfigMaps,
the clock) reaches it as a "poke": the `coral.dev/observed` annotation set to a digest of what
changed, written only when the digest differs. A fleet has one system and thousands of instances,
so pokes are batched (`SYSTEM_POKE_DELAY_S`); instances are queued in-process instead
(`handlers.instances`).
"""

from __future__ import annotations

import threading
import time
from typing import Any

import kopf

from coral_operator.api import names
from coral_operator.api.common import LabelSelector
from coral_operator.handlers.indexing import read_index
from coral_operator.kube import applying
from coral_operator.kube.workqueue import WorkQueue
from coral_operator.planning import naming, selection
from coral_operator.planning.observed import ObservedInstance, RobotNode

_lock = threading.Lock()
_poked: dict[tuple[str, str, str], str] = {}
_nodes: dict[str, tuple[Any, ...]] = {}


def poke(plural: str, namespace: str, name: str, digest: str) -> None:
    """Set the object's observed-digest annotation unless this process already set that value."""
    key = (plural, namespace, name)
    with _lock:
        if _poked.get(key) == digest:
            return
    applying.annotate(plural, namespace, name, {names.ANNOTATION_OBSERVED: digest})
    with _lock:
        _poked[key] = digest


_handled: dict[str, tuple[Any, ...]] = {}


def already_handled(uid: str, inputs: tuple[Any, ...]) -> bool:
    """Whether the object was reconciled from exactly these inputs; its own status writes are not inputs."""
    with _lock:
        return _handled.get(uid) == inputs


def handled(uid: str, inputs: tuple[Any, ...]) -> None:
    with _lock:
        _handled[uid] = inputs


def forget(uid: str) -> None:
    with _lock:
        _handled.pop(uid, None)


def retry_later(plural: str, namespace: str, name: str, uid: str, delay_s: float = 5.0) -> None:
    """After a failed pass (an API error, say), poke the object again so the pass is retried."""
    forget(uid)
    digest = f"retry-{time.monotonic_ns()}"
    timer = threading.Timer(delay_s, poke, args=(plural, namespace, name, digest))
    timer.daemon = True
    timer.start()


def _selected_digest(spec: dict[str, Any], robots: list[RobotNode]) -> str | None:
    try:
        selector = LabelSelector.model_validate(spec.get("robots") or {})
    except ValueError:
        return None
    chosen = selection.select_robots(selector, robots)
    return naming.content_hash([(r.robot, r.node_name, r.ready) for r in chosen])


@kopf.on.event("nodes", labels={names.LABEL_ROBOT: kopf.PRESENT})
def poke_on_robot_change(
    type: str | None,
    name: str,
    labels: kopf.Labels,
    robot_nodes: kopf.Index,
    coral_systems: kopf.Index,
    **_: Any,
) -> None:
    robot = next(iter(robot_nodes.get(("node", name), [])), None)
    summary = (
        ("gone",) if type == "DELETED" or robot is None else (tuple(sorted(labels.items())), robot.ready)
    )
    with _lock:
        # Heartbeats change a Node every few seconds; only labels and readiness matter here.
        if _nodes.get(name) == summary:
            return
        _nodes[name] = summary
    for namespace, node_name in [(k, n) for k in coral_systems for n in coral_systems[k]]:
        digest = _selected_digest(node_name[1], list(robot_nodes.get("all", [])))
        if digest is not None:
            poke("coralsystems", namespace, node_name[0], "robots-" + digest)


def _instances_digest(instances: list[ObservedInstance]) -> str:
    return naming.content_hash(
        sorted(
            (
                i.name,
                i.revision,
                i.ready,
                i.reachable,
                i.node_ready,
                i.root_status,
                i.stalled,
                bool(i.spec.get("retiring")),
            )
            for i in instances
        )
    )


# A fleet's instances change in bursts (a wave of robots becoming Ready); the system needs one
# pass per burst, not one per instance: the first change after a quiet spell pokes at once, later
# ones at most this often, each poke covering all changes since the last.
SYSTEM_POKE_DELAY_S = 0.5
_instances_index: dict[str, kopf.Index] = {}


def _poke_system(key: tuple[str, str]) -> None:
    index = _instances_index.get("index")
    if index is None:
        return
    observed = read_index(index, key)
    poke("coralsystems", key[0], key[1], "instances-" + _instances_digest(observed))


SYSTEM_POKES: WorkQueue[tuple[str, str]] = WorkQueue(
    _poke_system, workers=2, min_interval_s=SYSTEM_POKE_DELAY_S, name="system-poke"
)


@kopf.on.cleanup()
def stop_system_pokes(**_: Any) -> None:
    SYSTEM_POKES.stop()


@kopf.on.event(names.GROUP, names.VERSION, names.INSTANCE_PLURAL)
async def poke_system_on_instance_change(
    namespace: str, spec: kopf.Spec, coral_instances: kopf.Index, **_: Any
) -> None:
    system = spec.get("system")
    if system:
        _instances_index["index"] = coral_instances
        SYSTEM_POKES.ensure_started()
        SYSTEM_POKES.add((namespace, system))


@kopf.on.event("configmaps")
def poke_systems_on_source_change(
    type: str | None, namespace: str, name: str, body: kopf.Body, coral_systems: kopf.Index, **_: Any
) -> None:
    for system, spec in coral_systems.get(namespace, []):
        refs = [((spec.get(f) or {}).get("configMapRef") or {}).get("name") for f in ("tree", "parameters")]
        if name in refs:
            digest = naming.content_hash([type == "DELETED", body.get("data")])
            poke("coralsystems", namespace, system, f"configmap-{name}-{digest}")
