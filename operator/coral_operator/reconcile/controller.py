"""The operator's controller: one keyed work queue, two reconcilers, and the map from watch events to keys.

kopf's handlers (`handlers.watching`) call the `on_*` methods with what a watch event says; each
names the objects that need a pass as keys `(kind, namespace, name)` on the one queue. The queue
holds a key once however many events name it, never runs it on two workers at once, spaces its
passes (a fleet's system at most every `SYSTEM_INTERVAL_S`), retries a failed pass with backoff,
and runs delayed passes (a health timeout, a canary hold) in place of timers. See
docs/architecture.md.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from concurrent.futures import ThreadPoolExecutor
from typing import Any

from coral_core import names

from coral_operator.kube import observing
from coral_operator.kube.workqueue import WorkQueue
from coral_operator.kube.writer import KubeWriter, Writer
from coral_operator.planning.pods import PodSettings
from coral_operator.planning.policy import Policy
from coral_operator.reconcile import events
from coral_operator.reconcile.declarations import ImageDeclarations
from coral_operator.reconcile.indexes import Indexes, instances_on_node
from coral_operator.reconcile.instances import InstanceReconciler
from coral_operator.reconcile.memory import Memory
from coral_operator.reconcile.systems import SystemReconciler
from coral_operator.reconcile.trimming import Trimmer

SYSTEM = "CoralSystem"
INSTANCE = "CoralInstance"
Key = tuple[str, str, str]
"""(kind, namespace, name)."""

# A fleet's instances change in bursts (a wave of robots becoming Ready); the system needs one
# pass per burst, not one per instance, and a pass over a thousand robots is not free. But each
# robot of a rolling update waits for the pass that frees its budget, so the spacing is short.
SYSTEM_INTERVAL_S = 0.2
# kopf already gathers one object's events in a short window; a longer spacing here would only add
# itself to each step of a robot's ordered startup (pod created, Ready, next stage created).
INSTANCE_INTERVAL_S = 0.02
# A pass spends most of its time waiting on the API server (a pod created, a status written):
# with a thousand robots due at once, a handful of workers leaves keys waiting for a free one
# longer than the pass itself takes (the queue's log line says how late passes start).
WORKERS = 32
API_WRITERS = 16
"""Threads that carry one system pass's instance writes in parallel (they wait on the network)."""


class Controller:
    """Everything the operator runs between watch events and API writes; one per process."""

    def __init__(
        self,
        *,
        policy: Policy,
        post: events.Poster,
        memory: Memory | None = None,
        writer: Writer | None = None,
        workers: int = WORKERS,
        pod_settings: PodSettings | None = None,
        preflight_registries: frozenset[str] = frozenset(),
        on_pass: Callable[[str, bool, float, float], None] | None = None,
    ) -> None:
        """`on_pass(kind, failed, late_s, busy_s)` is told of every pass as it ends (metrics)."""
        self.memory = memory or Memory()
        self.indexes = Indexes()
        self.trimmer = Trimmer()
        self._pool = ThreadPoolExecutor(max_workers=API_WRITERS, thread_name_prefix="coral-api")
        self.queue: WorkQueue[Key] = WorkQueue(
            self._process,
            workers=workers,
            min_interval_s=_interval,
            name="coral",
            on_pass=None if on_pass is None else (lambda key, *outcome: on_pass(key[0], *outcome)),
        )
        shared: dict[str, Any] = {
            "memory": self.memory,
            "indexes": self.indexes,
            "writer": writer or KubeWriter(),
            "post": post,
        }
        self.instances = InstanceReconciler(
            **shared,
            requeue=lambda key, delay: self.queue.add((INSTANCE, *key), delay),
            wake_system=lambda key: self.queue.add((SYSTEM, *key)),
            pod_settings=pod_settings or PodSettings(policy=policy),
        )
        self.systems = SystemReconciler(
            **shared,
            requeue=lambda key, delay: self.queue.add((SYSTEM, *key), delay),
            policy=policy,
            pool=self._pool,
            wake_instance=lambda key: self.queue.add((INSTANCE, *key)),
            trim=self.trimmer.soon,
            declarations=ImageDeclarations(registries=preflight_registries),
        )

    def _process(self, key: Key) -> None:
        kind, namespace, name = key
        reconciler = self.systems if kind == SYSTEM else self.instances
        reconciler.reconcile((namespace, name))

    def start(self, **indexes: Mapping[Any, Any]) -> None:
        """Attach kopf's indexes and start the workers unless they run (see `WorkQueue.start` for
        why this is called from a resource handler)."""
        self.indexes.attach(**indexes)
        self.queue.ensure_started()

    def stop(self) -> None:
        self.trimmer.stop()
        self.queue.stop()
        self._pool.shutdown(wait=False, cancel_futures=True)

    # --- watch events to keys ----------------------------------------------------------------

    def on_system(
        self, *, deleted: bool, namespace: str, name: str, uid: str, body: Mapping[str, Any]
    ) -> None:
        """A system's spec or its rollout commands (`coral rollout undo`, `resume`) changed; its own
        status writes change neither, so they cost no pass."""
        key = (SYSTEM, namespace, name)
        if deleted:
            self.memory.forget_system(uid, namespace, name)
            self.memory.seen.forget(key)
            self.queue.forget(key)
            self.trimmer.soon()
            return
        metadata = body.get("metadata") or {}
        annotations = metadata.get("annotations") or {}
        inputs = (
            uid,
            metadata.get("generation"),
            annotations.get(names.ANNOTATION_ROLLOUT_UNDO),
            annotations.get(names.ANNOTATION_ROLLOUT_RESUME),
        )
        if self.memory.seen.changed(key, inputs):
            self.queue.add(key)

    def on_instance(
        self, *, deleted: bool, namespace: str, name: str, uid: str, body: Mapping[str, Any]
    ) -> None:
        """Pass the instance on any change but the echo of this process's own status write (which
        the pass that wrote it already accounted for), and its system when something the system
        reads of it changed."""
        key = (INSTANCE, namespace, name)
        system = (body.get("spec") or {}).get("system")
        if deleted:
            self.memory.forget_instance(uid, namespace, name)
            self.memory.seen.forget(key)
            self.queue.forget(key)
            self.trimmer.soon()
            if system:
                self.queue.add((SYSTEM, namespace, system))
            return
        version = (body.get("metadata") or {}).get("resourceVersion")
        own_write = self.memory.statuses.is_own(uid, version)
        # The echo of a system pass's move: that pass already handed it to the instance's pass.
        if not own_write and not self.memory.moved.is_own((namespace, name), version):
            self.queue.add(key)
        # The pass that wrote a status woke the system itself if the system reads a change in it.
        if system and self.memory.seen.changed(key, observing.instance_summary(body)) and not own_write:
            self.queue.add((SYSTEM, namespace, system))

    def on_pod(self, *, namespace: str, instance: str, pre_pull_of: str | None = None) -> None:
        """`pre_pull_of`: the system of a pre-pull pod, whose rollout waits on the pull."""
        self.queue.add((INSTANCE, namespace, instance))
        if pre_pull_of:
            self.queue.add((SYSTEM, namespace, pre_pull_of))

    def on_robot_node(
        self,
        *,
        deleted: bool,
        name: str,
        labels: Mapping[str, str],
        spec: Mapping[str, Any],
        status: Mapping[str, Any],
        annotations: Mapping[str, str] | None = None,
    ) -> None:
        """A robot came, went, changed labels, annotations or reachability; heartbeats alone change
        nothing."""
        robot = None if deleted else observing.robot_node(name, labels, status, spec, annotations)
        summary = (
            None
            if robot is None
            else (
                tuple(sorted(labels.items())),
                tuple(sorted(robot.annotations.items())),
                robot.ready,
                robot.reachable,
            )
        )
        if not self.memory.seen.changed(("Node", name), summary):
            return
        if deleted:
            self.memory.seen.forget(("Node", name))
        for namespace, instance in self.indexes.read("coral_instances", instances_on_node(name)):
            self.queue.add((INSTANCE, namespace, instance))
        for namespace, system in self.indexes.keys("coral_systems"):
            self.queue.add((SYSTEM, namespace, system))

    def on_config_map(self, *, namespace: str, name: str) -> None:
        """A source file of some system may have changed."""
        for system_namespace, system in self.indexes.keys("coral_systems"):
            if system_namespace != namespace:
                continue
            for record in self.indexes.read("coral_systems", (namespace, system)):
                refs = [
                    ((record.spec.get(field) or {}).get("configMapRef") or {}).get("name")
                    for field in ("tree", "parameters")
                ]
                if name in refs:
                    self.queue.add((SYSTEM, namespace, system))


def _interval(key: Key) -> float:
    return SYSTEM_INTERVAL_S if key[0] == SYSTEM else INSTANCE_INTERVAL_S
