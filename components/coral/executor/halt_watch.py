"""Follows `spec.halt` of the executor's own CoralInstance into its `HaltSignal`.

Started by `coral.executor.running` when the executor runs in a cluster (CORAL_INSTANCE and
CORAL_NAMESPACE set). One watch, narrowed to the instance by name: a halt reaches the tick loop
one watch event after the operator writes it, with no pod restart. The watch is listed again
after every end (the server's timeout, an expired version, a lost link), pausing longer after
each failure; while the link is down the robot keeps doing what it was last told (halted or not).
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Mapping
from typing import Any

from coral_core import names
from coral_core.halt import HaltRequest
from pydantic import ValidationError

from coral.executor.halting import HaltSignal
from coral.executor.kubernetes_sink import REQUEST_TIMEOUT_S, RETRY_MAX_S

LOG = logging.getLogger(__name__)
# The server ends each watch after this long; listing again then costs one small request.
WATCH_S = 300


def halt_of_instance(body: Mapping[str, Any]) -> HaltRequest | None:
    """The halt the instance asks for (None: run). A halt the executor cannot read still halts,
    without a park tree: stopping is what was asked."""
    spec = body.get("spec")
    halt = spec.get("halt") if isinstance(spec, Mapping) else None
    if halt is None:
        return None
    try:
        return HaltRequest.model_validate(halt)
    except ValidationError as error:
        LOG.warning("spec.halt of the CoralInstance is unreadable, halting without a park tree: %s", error)
        return HaltRequest()


class InstanceHaltWatch:
    """A daemon thread that keeps `signal` equal to the instance's `spec.halt`."""

    def __init__(self, api_client: Any, namespace: str, instance: str, signal: HaltSignal) -> None:
        from kubernetes import client

        self._api = client.CustomObjectsApi(api_client)
        self._namespace = namespace
        self._instance = instance
        self._signal = signal
        self._stopping = threading.Event()
        self._watch: Any = None
        self._thread = threading.Thread(target=self._run, name="halt-watch", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        self._stopping.set()
        if self._watch is not None:
            self._watch.stop()

    def _list_args(self) -> tuple[Any, ...]:
        return (names.GROUP, names.VERSION, self._namespace, names.INSTANCE_PLURAL)

    def _run(self) -> None:
        failures = 0
        while not self._stopping.is_set():
            try:
                self._follow()
                failures = 0
            except Exception as error:  # noqa: BLE001 - a lost link must not end the following
                failures += 1
                if failures == 1:
                    LOG.warning("Following the CoralInstance's spec.halt failed (retrying): %s", error)
                self._stopping.wait(min(2.0 ** (failures - 1), RETRY_MAX_S))

    def _follow(self) -> None:
        """Lists the instance, then watches it until the watch ends."""
        from kubernetes import watch

        selector = f"metadata.name={self._instance}"
        listing = self._api.list_namespaced_custom_object(
            *self._list_args(), field_selector=selector, _request_timeout=REQUEST_TIMEOUT_S
        )
        for item in listing.get("items") or []:
            self._signal.set(halt_of_instance(item))
        self._watch = watch.Watch()
        stream = self._watch.stream(
            self._api.list_namespaced_custom_object,
            *self._list_args(),
            field_selector=selector,
            resource_version=listing["metadata"]["resourceVersion"],
            timeout_seconds=WATCH_S,
            _request_timeout=(REQUEST_TIMEOUT_S[0], WATCH_S + REQUEST_TIMEOUT_S[1]),
        )
        for event in stream:
            if self._stopping.is_set() or event.get("type") == "ERROR":
                return  # an expired version: list again
            if event.get("type") in ("ADDED", "MODIFIED"):
                self._signal.set(halt_of_instance(event["object"]))
