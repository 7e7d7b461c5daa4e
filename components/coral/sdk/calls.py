"""Calls from behaviors (running in an executor) into their skillset over ROS 2.

Used inside behavior classes: `ServiceCall` sends a request without blocking the tick, polls its
future each tick, wakes the tree when the response arrives, enforces a timeout, cancels on halt,
and fails fast when the skillset behind it stopped (its heartbeat went silent). `LatestMessage`
reads the newest message of a topic, `TopicWait` waits for one with a timeout, and `publisher`
gives a cached publisher. The executor supplies the `CallContext` as `self.context`.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable
from typing import Any, Protocol

from coral_core.bt import Status


class CallContext(Protocol):
    """What the executor provides to behaviors (`self.context`) for ROS calls."""

    node: Any

    def service_client(self, srv_type: Any, service: str) -> Any: ...

    def subscription_cache(self, msg_type: Any, topic: str, latched: bool = False) -> Any: ...

    def publisher(self, msg_type: Any, topic: str, latched: bool = False) -> Any: ...

    def component_failure(self, component: str) -> str | None: ...

    def publish_cancel(self, service: str) -> None: ...

    def note_failure(self, behavior: Any, message: str) -> None: ...

    def wake_at(self, when: float) -> int:
        """Books a tick at monotonic time `when` (a deadline no event announces); a token back."""
        ...

    def cancel_wake(self, token: int) -> None: ...


def resolve_name(behavior: Any, name: str) -> str:
    """`~/x` -> `<skillset node FQN>/x` for the skillset that exported `behavior`; others unchanged."""
    if not name.startswith("~"):
        return name
    component = getattr(type(behavior), "CORAL_COMPONENT", None)
    if component is None:
        raise ValueError(
            f"name {name!r} is relative to a skillset, but this behavior was not loaded from one"
        )
    return component.node_fqn + name[1:]


def open_clients(nodes: Iterable[Any]) -> None:
    """Creates the service clients of every node whose class declares the services it calls
    (`CALLS`: (service type, name) pairs), before the tree's first tick.

    A new client is matched with its service by DDS discovery, about a tenth of a second after it
    is created. Created on first use, that delay lands in the middle of the mission, once per
    service (the SLAM example's first map save held its loop for 0.3 s); created with the tree, it
    passes while the tree starts. A name that cannot be resolved is left to the call itself, which
    fails with the reason.
    """
    for node in nodes:
        for srv_type, name in getattr(type(node), "CALLS", ()):
            try:
                _context_of(node).service_client(srv_type, resolve_name(node, name))
            except (ValueError, RuntimeError):
                continue


def _context_of(behavior: Any) -> CallContext:
    context = getattr(behavior, "context", None)
    if context is None or not hasattr(context, "service_client"):
        raise RuntimeError("behavior has no executor context: ROS calls need a Coral executor")
    return context  # type: ignore[no-any-return]


def note_refusal(behavior: Any, message: str) -> None:
    """Records why a behavior failed after its skillset answered (no call failed, the answer did)."""
    _context_of(behavior).note_failure(behavior, message)


def _fail(behavior: Any, context: CallContext, message: str) -> Status:
    if hasattr(behavior, "feedback_message"):
        behavior.feedback_message = message
    context.note_failure(behavior, message)
    return Status.FAILURE


class ServiceCall:
    """One asynchronous service request made by a behavior.

    `send` never blocks: when the service is not discovered yet, the request goes out on the
    first `poll` that finds it. `poll` returns RUNNING while waiting, SUCCESS with `response` set,
    or FAILURE with `message` set (timeout, or the skillset behind the service stopped).

    The tree needs no polling meanwhile (a behavior that only waits on a `ServiceCall` may set
    `SIGNALS_WAKE_UP`): the response wakes the tree, and the call books ticks with the executor
    for what no event announces, its deadline and, until the service is discovered, a retry
    every `DISCOVERY_POLL_S`.
    """

    DISCOVERY_POLL_S = 0.05

    def __init__(self, behavior: Any, srv_type: Any, service: str, *, timeout_s: float = 5.0) -> None:
        self.behavior = behavior
        self.context = _context_of(behavior)
        self.service = resolve_name(behavior, service)
        self.timeout_s = timeout_s
        self.client = self.context.service_client(srv_type, self.service)
        component = getattr(type(behavior), "CORAL_COMPONENT", None)
        self.component: str | None = component.name if component is not None else None
        self.response: Any = None
        self.message = ""
        self._request: Any = None
        self._future: Any = None
        self._deadline = 0.0
        self._booked: list[int] = []

    def send(self, request: Any) -> Status:
        self._request = request
        self._future = None
        self.response = None
        self.message = ""
        self._deadline = time.monotonic() + self.timeout_s
        self._book(self._deadline)
        return self.poll()

    def _book(self, when: float) -> None:
        wake_at = getattr(self.context, "wake_at", None)
        if wake_at is not None:
            self._booked.append(wake_at(when))

    def _cancel_bookings(self) -> None:
        cancel = getattr(self.context, "cancel_wake", None)
        if cancel is not None:
            for token in self._booked:
                cancel(token)
        self._booked.clear()

    def _dispatch(self) -> None:
        self._future = self.client.call_async(self._request)
        wake = getattr(self.behavior, "wake_up", None)
        if wake is not None:
            self._future.add_done_callback(lambda _future: wake())

    def poll(self) -> Status:
        if self._request is None:
            raise RuntimeError("ServiceCall.poll() before send()")
        if self._future is not None and self._future.done():
            self.response = self._future.result()
            self._request = None
            self._cancel_bookings()
            return Status.SUCCESS if self.response is not None else self._finish_failed("no response")
        if self.component is not None:
            failure = self.context.component_failure(self.component)
            if failure is not None:
                return self._finish_failed(f"skillset {self.component} is unavailable: {failure}")
        if self._future is None and self.client.service_is_ready():
            self._dispatch()
        elif self._future is None:
            self._book(time.monotonic() + self.DISCOVERY_POLL_S)
        if time.monotonic() >= self._deadline:
            what = "no response" if self._future is not None else "service not available"
            # The skillset may still be working on a timed-out request: tell it to stop.
            if self.in_flight:
                self.context.publish_cancel(self.client.service_name)
            return self._finish_failed(f"{what} from {self.service} within {self.timeout_s:g} s")
        return Status.RUNNING

    def _finish_failed(self, message: str) -> Status:
        self._abandon()
        self.message = message
        return _fail(self.behavior, self.context, message)

    def _abandon(self) -> None:
        self._cancel_bookings()
        if self._future is not None and not self._future.done():
            self.client.remove_pending_request(self._future)
            self._future.cancel()
        self._future = None
        self._request = None

    @property
    def in_flight(self) -> bool:
        return self._future is not None and not self._future.done()

    def cancel(self) -> None:
        """Drops the pending response and asks the skillset to stop serving the request."""
        was_in_flight = self.in_flight
        self._abandon()
        if was_in_flight:
            self.context.publish_cancel(self.client.service_name)


class LatestMessage:
    """The newest message on a topic, received in the executor's ROS thread; `get` never blocks.

    `latched=True` subscribes transient-local, to get the last message a publisher sent before
    the subscription existed (the publisher must be transient-local too).
    """

    def __init__(self, behavior: Any, msg_type: Any, topic: str, *, latched: bool = False) -> None:
        self.context = _context_of(behavior)
        self.topic = resolve_name(behavior, topic)
        self._cache = self.context.subscription_cache(msg_type, self.topic, latched)

    def get(self, max_age_s: float | None = None) -> Any:
        """The newest message, or None when none arrived (or the newest is older than `max_age_s`)."""
        message, received_at = self._cache.latest()
        if message is None:
            return None
        if max_age_s is not None and time.monotonic() - received_at > max_age_s:
            return None
        return message


class TopicWait:
    """Waits, without blocking the tick, for a message on a topic that `accept` approves.

    `start()` then `poll()` each tick: RUNNING until the newest message satisfies `accept`
    (SUCCESS, with `message` set), FAILURE after `timeout_s` or when the skillset stopped.
    """

    def __init__(
        self,
        behavior: Any,
        msg_type: Any,
        topic: str,
        *,
        accept: Callable[[Any], bool] = lambda _message: True,
        timeout_s: float = 5.0,
        latched: bool = False,
    ) -> None:
        self.behavior = behavior
        self.latest = LatestMessage(behavior, msg_type, topic, latched=latched)
        self.context = self.latest.context
        self.accept = accept
        self.timeout_s = timeout_s
        component = getattr(type(behavior), "CORAL_COMPONENT", None)
        self.component: str | None = component.name if component is not None else None
        self.message: Any = None
        self._deadline = 0.0

    def start(self) -> Status:
        self._deadline = time.monotonic() + self.timeout_s
        self.message = None
        return self.poll()

    def poll(self) -> Status:
        candidate = self.latest.get()
        if candidate is not None and self.accept(candidate):
            self.message = candidate
            return Status.SUCCESS
        if self.component is not None:
            failure = self.context.component_failure(self.component)
            if failure is not None:
                return _fail(
                    self.behavior, self.context, f"skillset {self.component} is unavailable: {failure}"
                )
        if time.monotonic() >= self._deadline:
            what = "no message" if candidate is None else "no accepted message"
            return _fail(
                self.behavior, self.context, f"{what} on {self.latest.topic} within {self.timeout_s:g} s"
            )
        return Status.RUNNING


def publisher(behavior: Any, msg_type: Any, topic: str, *, latched: bool = False) -> Any:
    """A publisher on the executor's node, created once per (type, topic, latched) and reused."""
    context = _context_of(behavior)
    return context.publisher(msg_type, resolve_name(behavior, topic), latched)
