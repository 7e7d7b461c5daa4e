"""What an executor received from its peers: pending triggers, acknowledgements, shared values.

Pure and thread-safe; fed by `hub` callbacks (ROS thread) and read by behaviors (tick thread).
"""

from __future__ import annotations

import threading
from collections import deque

from coral.coordination import messages


class Inbox:
    def __init__(self, hostname: str) -> None:
        self.hostname = hostname
        self._lock = threading.Lock()
        self._seen_triggers: set[str] = set()
        self._pending: dict[str, deque[str]] = {}
        self._acked: set[str] = set()
        self._values: dict[tuple[str, str], messages.SharedValue] = {}
        self._seen_values: set[str] = set()

    def accept_trigger(self, trigger: messages.Trigger) -> bool:
        """Records a trigger addressed to this host; True when it should be acknowledged.

        A retransmission (same id) is acknowledged again but queued only once.
        """
        if trigger.target != self.hostname:
            return False
        with self._lock:
            if trigger.id not in self._seen_triggers:
                self._seen_triggers.add(trigger.id)
                self._pending.setdefault(trigger.process, deque()).append(trigger.id)
        return True

    def take_trigger(self, process: str) -> str | None:
        """Consumes the oldest pending trigger for `process`; its id, or None."""
        with self._lock:
            queue = self._pending.get(process)
            return queue.popleft() if queue else None

    def pending(self, process: str) -> int:
        with self._lock:
            return len(self._pending.get(process, ()))

    def accept_ack(self, ack: messages.Ack) -> None:
        with self._lock:
            self._acked.add(ack.id)

    def acknowledged(self, message_id: str) -> bool:
        with self._lock:
            return message_id in self._acked

    def accept_value(self, value: messages.SharedValue) -> bool:
        """Keeps the newest value per (sender, key) addressed to this host or to everyone."""
        if value.target not in (self.hostname, messages.ANY_HOST):
            return False
        with self._lock:
            if value.id in self._seen_values:
                return False
            self._seen_values.add(value.id)
            key = (value.sender, value.key)
            current = self._values.get(key)
            if current is None or value.stamp >= current.stamp:
                self._values[key] = value
        return True

    def value(self, key: str, sender: str = messages.ANY_HOST) -> messages.SharedValue | None:
        """The newest value for `key` (from `sender`, or from anyone when `sender` is `*`)."""
        with self._lock:
            candidates = [
                value
                for (from_host, name), value in self._values.items()
                if name == key and sender in (messages.ANY_HOST, from_host)
            ]
        return max(candidates, key=lambda value: value.stamp) if candidates else None
