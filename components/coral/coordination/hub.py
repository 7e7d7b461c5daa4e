"""The ROS side of coordination: publishes and receives triggers, acknowledgements and shared values.

Created by the executor on its node (`context.coordination`); coordination behaviors call
`send_trigger`, `share` and read `inbox`. Topics are reliable and transient-local, so a trigger
published before the waiting executor started is delivered when it joins (while the sender runs).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from coral.coordination import messages
from coral.coordination.inbox import Inbox


class CoordinationHub:
    def __init__(self, node: Any, hostname: str, wake_up: Callable[[], None]) -> None:
        from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
        from std_msgs.msg import String

        self.hostname = hostname
        self.inbox = Inbox(hostname)
        self._wake_up = wake_up
        self._string = String
        qos = QoSProfile(
            history=HistoryPolicy.KEEP_LAST,
            depth=messages.HISTORY_DEPTH,
            reliability=ReliabilityPolicy.RELIABLE,
            durability=DurabilityPolicy.TRANSIENT_LOCAL,
        )
        self._triggers = node.create_publisher(String, messages.TRIGGER_TOPIC, qos)
        self._acks = node.create_publisher(String, messages.ACK_TOPIC, qos)
        self._values = node.create_publisher(String, messages.VALUE_TOPIC, qos)
        node.create_subscription(String, messages.TRIGGER_TOPIC, self._on_trigger, qos)
        node.create_subscription(String, messages.ACK_TOPIC, self._on_ack, qos)
        node.create_subscription(String, messages.VALUE_TOPIC, self._on_value, qos)

    def publishers(self) -> list[Any]:
        return [self._triggers, self._acks, self._values]

    def _publish(self, publisher: Any, message: Any) -> None:
        publisher.publish(self._string(data=messages.encode(message)))

    def send_trigger(self, target: str, process: str, message_id: str) -> None:
        """(Re)sends a trigger; receivers recognise a resend by its id."""
        self._publish(self._triggers, messages.Trigger(message_id, self.hostname, target, process))

    def share(self, key: str, value: str, target: str = messages.ANY_HOST) -> None:
        shared = messages.SharedValue(messages.new_id(), self.hostname, target, key, value, time.time())
        self._publish(self._values, shared)

    def _on_trigger(self, message: Any) -> None:
        trigger = messages.decode_trigger(message.data)
        if trigger is not None and self.inbox.accept_trigger(trigger):
            self._publish(self._acks, messages.Ack(trigger.id, self.hostname))
            self._wake_up()

    def _on_ack(self, message: Any) -> None:
        ack = messages.decode_ack(message.data)
        if ack is not None:
            self.inbox.accept_ack(ack)
            self._wake_up()

    def _on_value(self, message: Any) -> None:
        value = messages.decode_value(message.data)
        if value is not None and self.inbox.accept_value(value):
            self._wake_up()
