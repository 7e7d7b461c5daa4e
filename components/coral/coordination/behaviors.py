"""Coordination behaviors, built into every executor (registered by `coral.coordination.register`).

They reach the executor's `CoordinationHub` through `self.context.coordination` and never block:
messages go out and arrive on the executor's ROS thread, which wakes the tree.
"""

from __future__ import annotations

import time
from typing import Any

from coral_core.bt import PortDirection, PortSpec, Status
from coral_core.bt.leaves import StatefulAction, SyncAction

from coral.coordination import messages

# Resend an unacknowledged trigger this often: DDS is reliable once matched, but a peer that is
# still discovering us (or restarting) misses what was sent before it matched.
RESEND_PERIOD_S = 0.5


def _hub(node: Any) -> Any:
    hub = getattr(node.context, "coordination", None)
    if hub is None:
        raise RuntimeError("coordination behaviors need a Coral executor (no coordination hub in context)")
    return hub


def _timeout_s(node: Any) -> float | None:
    timeout_ms = node.get_input("timeout_ms")
    return None if timeout_ms is None or int(timeout_ms) <= 0 else int(timeout_ms) / 1000.0


def _fail(node: Any, message: str) -> Status:
    node.feedback_message = message
    note = getattr(node.context, "note_failure", None)
    if note is not None:
        note(node, message)
    return Status.FAILURE


class TriggerRemote(StatefulAction):
    """Sends trigger `process_identifier` to the executor whose hostname is `remote_hostname`.

    RUNNING until the remote executor acknowledges receipt; SUCCESS then; FAILURE when no
    acknowledgement arrives within `timeout_ms` (peer absent or unreachable). Resending keeps the
    same message id, so the receiver counts the trigger once.
    """

    PORTS = [
        PortSpec(
            "remote_hostname", PortDirection.INPUT, "string", description="Hostname of the receiving executor"
        ),
        PortSpec("process_identifier", PortDirection.INPUT, "string", description="Name of the trigger"),
        PortSpec(
            "timeout_ms",
            PortDirection.INPUT,
            "int",
            default="10000",
            description="Give up without an acknowledgement after this long (0: never)",
        ),
    ]

    def on_start(self) -> Status:
        self.hub = _hub(self)
        self.target = str(self.get_input("remote_hostname"))
        self.process = str(self.get_input("process_identifier"))
        self.message_id = messages.new_id()
        timeout_s = _timeout_s(self)
        self.deadline = None if timeout_s is None else time.monotonic() + timeout_s
        self.last_sent = time.monotonic()
        self.hub.send_trigger(self.target, self.process, self.message_id)
        self.feedback_message = f"sent {self.process} to {self.target}"
        return Status.RUNNING

    def on_running(self) -> Status:
        if self.hub.inbox.acknowledged(self.message_id):
            self.feedback_message = f"{self.target} acknowledged {self.process}"
            return Status.SUCCESS
        now = time.monotonic()
        if self.deadline is not None and now >= self.deadline:
            return _fail(self, f"{self.target} did not acknowledge trigger {self.process} in time")
        if now - self.last_sent >= RESEND_PERIOD_S:
            self.hub.send_trigger(self.target, self.process, self.message_id)
            self.last_sent = now
        return Status.RUNNING

    def on_halted(self) -> None:
        self.feedback_message = "halted"


class WaitForRemoteTrigger(StatefulAction):
    """Waits for trigger `process_identifier` addressed to this executor's hostname.

    SUCCESS when one arrives (including one received before this node started, which waits in
    the inbox); each trigger is consumed once. RUNNING while waiting. FAILURE after `timeout_ms`
    (0, the default, waits forever as in Coral's trees).
    """

    PORTS = [
        PortSpec("process_identifier", PortDirection.INPUT, "string", description="Name of the trigger"),
        PortSpec(
            "timeout_ms",
            PortDirection.INPUT,
            "int",
            default="0",
            description="Fail after this long without the trigger (0: wait forever)",
        ),
    ]

    def on_start(self) -> Status:
        self.hub = _hub(self)
        self.process = str(self.get_input("process_identifier"))
        timeout_s = _timeout_s(self)
        self.deadline = None if timeout_s is None else time.monotonic() + timeout_s
        return self.on_running()

    def on_running(self) -> Status:
        if self.hub.inbox.take_trigger(self.process) is not None:
            self.feedback_message = f"received {self.process}"
            return Status.SUCCESS
        if self.deadline is not None and time.monotonic() >= self.deadline:
            return _fail(self, f"trigger {self.process} did not arrive in time")
        self.feedback_message = f"waiting for {self.process}"
        return Status.RUNNING


class ShareValue(SyncAction):
    """Publishes `value` under `key` to `remote_hostname` (`*`: every executor). Always SUCCESS."""

    PORTS = [
        PortSpec("key", PortDirection.INPUT, "string", description="Name of the shared value"),
        PortSpec("value", PortDirection.INPUT, "string", description="Value to share (as text)"),
        PortSpec(
            "remote_hostname",
            PortDirection.INPUT,
            "string",
            default=messages.ANY_HOST,
            description="Receiving executor's hostname, or * for all",
        ),
    ]

    def tick(self) -> Status:
        _hub(self).share(
            str(self.get_input("key")), str(self.get_input("value")), str(self.get_input("remote_hostname"))
        )
        return Status.SUCCESS


class WaitForSharedValue(StatefulAction):
    """Writes the newest value shared under `key` (from `sender_hostname`, `*`: anyone) to `value`.

    SUCCESS once a value is known (shared earlier counts); RUNNING until then; FAILURE after
    `timeout_ms` (0: wait forever).
    """

    PORTS = [
        PortSpec("key", PortDirection.INPUT, "string", description="Name of the shared value"),
        PortSpec(
            "sender_hostname",
            PortDirection.INPUT,
            "string",
            default=messages.ANY_HOST,
            description="Only accept values from this executor (* for any)",
        ),
        PortSpec(
            "timeout_ms",
            PortDirection.INPUT,
            "int",
            default="0",
            description="Fail after this long without a value (0: wait forever)",
        ),
        PortSpec("value", PortDirection.OUTPUT, "string", description="The received value"),
    ]

    def on_start(self) -> Status:
        self.hub = _hub(self)
        self.key = str(self.get_input("key"))
        self.sender = str(self.get_input("sender_hostname"))
        timeout_s = _timeout_s(self)
        self.deadline = None if timeout_s is None else time.monotonic() + timeout_s
        return self.on_running()

    def on_running(self) -> Status:
        shared = self.hub.inbox.value(self.key, self.sender)
        if shared is not None:
            self.set_output("value", shared.value)
            self.feedback_message = f"{self.key} from {shared.sender}"
            return Status.SUCCESS
        if self.deadline is not None and time.monotonic() >= self.deadline:
            return _fail(self, f"no value for {self.key} arrived in time")
        return Status.RUNNING
