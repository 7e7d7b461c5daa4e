"""Writes an executor's tree summary into `status.tree` / `status.plugins` of its own CoralInstance.

Plugged into the executor with `--sink coral.executor.kubernetes_sink:create_sink` (the operator
puts it in the executor's default command). It patches only when the summary changed, at most
once per `min_interval_s`, with the last pending summary flushed by a background thread and on
close. It authenticates as the robot's executor ServiceAccount, whose Role allows nothing but
this status patch.

A robot's link to the API server comes and goes, so every patch has a deadline
(`REQUEST_TIMEOUT_S`): a request that stalls on a dead connection would otherwise hold the sink
forever, freezing the robot's status and keeping a finished executor from exiting. A failed patch
is retried by the background thread with a growing pause (up to `RETRY_MAX_S`) even when the
summary does not change again, which is the case once a tree has ended; an answer that a retry
would get again (`_FINAL_REFUSALS`) waits for the next change instead. Closing keeps trying for
`finished_grace_s` when the tree ended by itself (its result is what the mission is for, and a
robot that finished out of reach reports it when it is back), or for `close_grace_s` when a
signal stopped it (within the pod's grace period). An outage is logged when it starts (once per
kind of error) and when it ends.
"""

from __future__ import annotations

import logging
import os
import threading
import time
from collections.abc import Callable
from datetime import UTC, datetime
from typing import Any

from coral_core import keys, names
from coral_core.instance_status import (
    CoralInstanceStatus,
    NoProgress,
    PluginState,
    TreeFailure,
    TreeHalt,
    TreeState,
)

LOG = logging.getLogger(__name__)
Patcher = Callable[[dict[str, Any]], None]

# (connect, read) seconds. A status patch answers in milliseconds; the read deadline leaves room
# for an API server under load without letting a dead connection hold the sink for long.
REQUEST_TIMEOUT_S = (5.0, 10.0)
# Pauses after consecutive failed patches double from 1 s up to this, so a fleet whose API server
# is away does not hammer it on its return.
RETRY_MAX_S = 30.0
# How long closing waits for the last summary to land after a signal: within a pod's default 30 s
# grace period.
CLOSE_GRACE_S = 20.0
# ... and after the tree ended by itself, when nothing is waiting for the process to go.
FINISHED_GRACE_S = 600.0
# The executor's exit codes from 128 on mean a signal stopped it (`coral.executor.running`).
_STOPPED_BY_SIGNAL = 128
# Answers that the same patch would get again: the instance is gone (its system was deleted, which
# also stops the executor), the identity may not write it, or the body is refused. Retrying them
# would only hold a stopping pod.
_FINAL_REFUSALS = frozenset({400, 403, 404, 422})
# Records someone waits on (`coral halt --wait`): patched at once rather than after the interval,
# unless a failure's pause holds the sink. Two per halt, so the rate limit keeps its purpose.
_URGENT_EVENTS = frozenset({"halted", "resumed"})


def _rfc3339(seconds: float | None) -> str | None:
    if seconds is None:
        return None
    return datetime.fromtimestamp(float(seconds), UTC).strftime("%Y-%m-%dT%H:%M:%SZ")


def _degraded(condition: dict[str, Any]) -> list[str]:
    """`plugins.degraded` from a `LibraryDegraded` condition: its message while it holds."""
    return [str(condition.get("message", ""))] if condition.get("status") == "True" else []


def summarize(state: CoralInstanceStatus, record: dict[str, Any]) -> CoralInstanceStatus:
    """The status summary after one executor record (pure; unknown events change nothing).

    `state` and the result set only `tree` and `plugins`, the executor's fields; `to_patch()` gives
    what to send, a null among it clearing a field that was set before.
    """
    tree = state.tree.model_copy() if state.tree is not None else TreeState()
    plugins = state.plugins.model_copy() if state.plugins is not None else PluginState()
    event = record.get("event")
    if event == "status":
        tree.root_status = str(record.get("root_status", tree.root_status))  # type: ignore[assignment]
        tree.tick_count = int(record.get("tick_count", tree.tick_count))
        tree.active_path = str(record.get("active_path") or "")
        if record.get("last_transition_time") is not None:
            tree.last_transition_time = _rfc3339(record["last_transition_time"])
        failure = record.get("last_failure") or {}
        if failure.get("path") or failure.get("message"):
            when = {"time": _rfc3339(failure["time"])} if failure.get("time") is not None else {}
            tree.last_failure = TreeFailure(
                path=str(failure.get("path", "")), message=str(failure.get("message", "")), **when
            )
        stuck = record.get("no_progress") or {}
        if stuck:
            tree.no_progress = NoProgress(
                path=str(stuck.get("path", "")),
                message=str(stuck.get("message", "")),
                since=_rfc3339(stuck.get("since")),
            )
        elif tree.no_progress is not None:
            tree.no_progress = None  # a merge patch's null clears the field
        for condition in record.get("conditions") or []:
            if condition.get("type") == "LibraryDegraded":
                plugins.degraded = _degraded(condition)
        tree.message = ""
    elif event == "waiting":
        missing = [str(m) for m in record.get("missing", [])]
        plugins.missing = missing
        if "root_status" not in tree.model_fields_set:
            tree.root_status = "IDLE"
        tree.message = "Waiting for node types: " + ", ".join(missing)
    elif event == "plugins":
        plugins.loaded = sorted(str(p.get("component", "")) for p in record.get("loaded", []))
        plugins.conflicts = [str(c.get("message", "")) for c in record.get("conflicts", [])] + [
            f"{r.get('plugin')} refused: {r.get('reason')}" for r in record.get("refused", [])
        ]
    elif event == "condition" and record.get("type") == "PluginsReady" and record.get("status") == "True":
        plugins.missing = []
    elif event == "condition" and record.get("type") == "LibraryDegraded":
        plugins.degraded = _degraded(record)
    elif event == "halted":
        halted = {"since": _rfc3339(record.get("since"))} | {
            key: record.get(key) for key in ("park_tree", "park_status")
        }
        tree.halted = TreeHalt(**{key: value for key, value in halted.items() if value is not None})
    elif event == "resumed":
        tree.halted = None  # a merge patch's null clears the field
    elif event in ("finished", "error"):
        if record.get("status"):
            tree.root_status = str(record["status"])  # type: ignore[assignment]
        if record.get("message") or record.get("error"):
            tree.message = str(record.get("message") or record.get("error"))
    else:
        return state
    result = state.model_copy()
    if tree.model_fields_set:
        result.tree = tree
    if plugins.model_fields_set:
        for empty in ("loaded", "missing"):
            if empty not in plugins.model_fields_set:
                setattr(plugins, empty, [])
        result.plugins = plugins
    return result


class KubernetesStatusSink:
    """Executor status sink: rate-limited, on-change merge patches of the instance's status."""

    def __init__(
        self,
        patcher: Patcher,
        *,
        min_interval_s: float = 1.0,
        close_grace_s: float = CLOSE_GRACE_S,
        finished_grace_s: float = FINISHED_GRACE_S,
        clock: Callable[[], float] = time.monotonic,
        wall: Callable[[], float] = time.time,
        background: bool = True,
    ) -> None:
        self._patcher = patcher
        self._interval = min_interval_s
        self._close_grace = close_grace_s
        self._finished_grace = finished_grace_s
        self._ended_by_itself = False
        self._clock = clock
        self._wall = wall
        self._state = CoralInstanceStatus()
        self._written: dict[str, Any] = {}
        """The last patch that landed, without `tree.updatedAt`."""
        self._not_before = float("-inf")
        self._failures = 0
        self._refused = False
        self._lock = threading.Lock()
        # One patch at a time, so patches land in the order their states were taken: a stale patch
        # still in flight must not overwrite the final one.
        self._sending = threading.Lock()
        self._wake = threading.Event()
        self._closing = threading.Event()
        self._errors: set[str] = set()
        self.patches = 0
        self._thread: threading.Thread | None = None
        if background:
            self._thread = threading.Thread(target=self._flush_loop, name="k8s-status-sink", daemon=True)
            self._thread.start()

    def emit(self, record: dict[str, Any]) -> None:
        with self._lock:
            self._state = summarize(self._state, record)
            if record.get("event") in _URGENT_EVENTS and not self._failures:
                self._not_before = float("-inf")
            if record.get("event") == "finished":
                self._ended_by_itself = int(record.get("exit_code") or 0) < _STOPPED_BY_SIGNAL
        if self._thread is not None:
            # The tick thread never waits on the API server: the background thread sends.
            self._wake.set()
        else:
            self.flush()

    @property
    def pending(self) -> bool:
        """Whether the summary has changed since the last patch that landed."""
        with self._lock:
            return self._state.to_patch() != self._written

    def flush(self) -> bool:
        """Patch if the summary changed and the rate limit (or a failure's pause) allows; True if it
        patched. A flush that finds a patch in flight leaves the change to the background loop
        (closing, which must not leave it, waits for that patch instead)."""
        if not self._sending.acquire(blocking=False):
            self._wake.set()
            return False
        try:
            return self._send(force=False)
        finally:
            self._sending.release()

    def _send(self, force: bool) -> bool:
        with self._lock:
            state = self._state.to_patch()
            if state == self._written:
                return False
            if not force and self._clock() < self._not_before:
                self._wake.set()
                return False
            self._not_before = self._clock() + self._interval
        written = {key: dict(value) for key, value in state.items()}
        if keys.INSTANCE_STATUS.tree in state:
            state[keys.INSTANCE_STATUS.tree][keys.TREE.updated_at] = _rfc3339(self._wall())
        try:
            self._patcher({"status": state})
        except Exception as error:  # noqa: BLE001 - a sink must never stop the mission
            self._failed(error)
            return False
        with self._lock:
            self._written = written
            self.patches += 1
            failures, self._failures = self._failures, 0
            self._refused = False
            self._errors.clear()
        if failures:
            LOG.warning("Status patches of the CoralInstance land again, after %d failed", failures)
        return True

    def _failed(self, error: Exception) -> None:
        status = getattr(error, "status", None)
        kind = type(error).__name__ + str(status or "")
        refused = status in _FINAL_REFUSALS
        with self._lock:
            self._failures += 1
            self._refused = refused
            pause = min(2.0 ** (self._failures - 1), RETRY_MAX_S)
            self._not_before = self._clock() + max(self._interval, pause)
            first_of_kind = kind not in self._errors
            self._errors.add(kind)
        if first_of_kind:
            then = "tried again with the next change" if refused else "retrying"
            LOG.warning("Status patch of the CoralInstance failed (%s): %s", then, error)
        if not refused:
            # Retried without waiting for the next change: a finished tree has none.
            self._wake.set()

    def _flush_loop(self) -> None:
        while True:
            self._wake.wait()
            self._wake.clear()
            if self._closing.is_set():
                return
            delay = self._not_before - self._clock()
            if delay > 0 and self._closing.wait(delay):
                return
            self.flush()

    def close(self) -> None:
        """Stops the background thread and patches the last summary, retrying for `finished_grace_s`
        after a tree that ended by itself, else for `close_grace_s`."""
        grace = self._finished_grace if self._ended_by_itself else self._close_grace
        deadline = time.monotonic() + grace
        self._closing.set()
        self._wake.set()
        if self._thread is not None:
            # A patch in flight ends within its request timeout.
            self._thread.join(timeout=max(0.0, deadline - time.monotonic()))
        warned = False
        while self.pending:
            remaining = deadline - time.monotonic()
            if remaining <= 0 or not self._sending.acquire(timeout=remaining):
                LOG.warning("The tree's last status was not written: the API server did not take it in time")
                return
            try:
                if self._send(force=True):
                    return
            finally:
                self._sending.release()
            if self._refused:
                LOG.warning("The tree's last status was not written: the API server refused it")
                return
            if not warned:
                warned = True
                LOG.warning("Trying for up to %.0f s more to write the tree's last status", remaining)
            with self._lock:
                pause = self._not_before - self._clock()
            time.sleep(min(max(pause, 0.0), max(0.0, deadline - time.monotonic())))


def build_patcher(
    api_client: Any,
    namespace: str,
    instance: str,
    *,
    api: Any = None,
    timeout: tuple[float, float] = REQUEST_TIMEOUT_S,
) -> Patcher:
    """A patcher that merge-patches `coralinstances/<instance>/status` through `api_client`, each
    request bounded by `timeout` (connect, read seconds).

    `api` replaces the client's CustomObjectsApi (the contract test records the address with it).
    """
    if api is None:
        from kubernetes import client

        api = client.CustomObjectsApi(api_client)

    def patch(body: dict[str, Any]) -> None:
        api.patch_namespaced_custom_object_status(
            names.GROUP,
            names.VERSION,
            namespace,
            names.INSTANCE_PLURAL,
            instance,
            body,
            _content_type="application/merge-patch+json",
            _request_timeout=timeout,
        )

    return patch


def instance_address(options: dict[str, Any]) -> tuple[str, str]:
    """(namespace, instance) of the executor's own CoralInstance, from `options` or CORAL_NAMESPACE
    and CORAL_INSTANCE (the operator sets both in every component's environment)."""
    instance = options.get("instance") or os.environ.get("CORAL_INSTANCE")
    namespace = options.get("namespace") or os.environ.get("CORAL_NAMESPACE")
    if not instance or not namespace:
        raise ValueError(
            "the Kubernetes status sink needs CORAL_INSTANCE and CORAL_NAMESPACE in the environment"
        )
    return namespace, instance


def executor_api_client() -> Any:
    """An API client with the pod's ServiceAccount (or KUBECONFIG outside a cluster), named as the
    executor in audit logs and as the field manager of its writes in managedFields."""
    from kubernetes import client, config
    from kubernetes.config.config_exception import ConfigException

    configuration = client.Configuration()
    try:
        config.load_incluster_config(client_configuration=configuration)
    except ConfigException:
        config.load_kube_config(client_configuration=configuration)
    api = client.ApiClient(configuration)
    api.user_agent = names.EXECUTOR_MANAGER
    return api


def create_sink(options: dict[str, Any]) -> KubernetesStatusSink:
    """Factory for the executor's `--sink`: instance from CORAL_INSTANCE / CORAL_NAMESPACE, credentials
    from the pod's ServiceAccount (or KUBECONFIG outside a cluster)."""
    namespace, instance = instance_address(options)
    api = executor_api_client()
    interval = float(options.get("min_interval_s") or os.environ.get("CORAL_STATUS_MIN_INTERVAL_S", "1.0"))
    finished_grace = float(
        options.get("finished_grace_s") or os.environ.get("CORAL_STATUS_FINISHED_GRACE_S", FINISHED_GRACE_S)
    )
    return KubernetesStatusSink(
        build_patcher(api, namespace, instance), min_interval_s=interval, finished_grace_s=finished_grace
    )
