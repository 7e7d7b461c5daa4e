"""The snapshot skillset's ROS 2 node: buffers configured topics raw and saves snapshots on request.

Run with `python -m coral_skillsets.snapshot --plugins DIR [--params FILE]`. Parameters (node
`snapshot`): topics (list), types (list beside topics, e.g. sensor_msgs/msg/PointCloud2: subscribed
at start; without it, types are taken from the ROS graph once the topics appear), slop_s
(synchronisation tolerance), buffer_size (messages kept per topic), output_dir (relative paths
resolve against $CORAL_OUTPUT_DIR), subscribe (`always`, the default, or `on_request`),
request_wait_s (with `on_request`: how long a request waits for its messages, default 5).
Messages are kept as raw CDR, so buffering a LiDAR topic costs no deserialisation. A snapshot is
a folder with one `.cdr` file per topic and `snapshot.json`.

With `subscribe: always` the topics are buffered from the start and a snapshot holds the newest
messages at the time of the request; a request that finds no snapshot to make fails at once. With
`subscribe: on_request` they are buffered from the start until the first snapshot is taken, and
after that only while a request is being served. Every request is answered at once from what is
buffered when that makes a snapshot, and otherwise waits (cancellable, up to `request_wait_s`) for
the first messages that do; a request that subscribed for itself saves them and unsubscribes. A
mission that takes a snapshot now and then thus does not pay for receiving every LiDAR scan in
between; the price is that a later snapshot holds the next messages after its request, not the
last ones before it. The first snapshot sees what was sent before it was requested, so a source
that plays once (a bag) cannot pass unseen while the mission starts up; and a mission that asks
for it before its data flows gets it as soon as the data arrives, after which the skillset stops
receiving the stream (a LiDAR at full rate costs every process that receives it CPU).
"""

from __future__ import annotations

import importlib
import json
import os
import threading
import time
from pathlib import Path
from typing import Any

from coral.sdk import CancelToken, Skillset
from coral_skillsets.snapshot import behaviors, buffering
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.qos import QoSProfile, ReliabilityPolicy
from std_srvs.srv import Trigger

SUBSCRIBE_MODES = ("always", "on_request")


class SnapshotSkillset(Skillset):
    NAME = "snapshot"
    BEHAVIORS = [behaviors.TakeSnapshot]

    def on_start(self) -> None:
        self.topics = [t for t in (self.param("topics", [""]) or []) if t]
        if not self.topics:
            raise ValueError("snapshot: the 'topics' parameter lists no topic")
        self.slop_ns = int(float(self.param("slop_s", 0.01)) * 1e9)
        self.buffer_size = int(self.param("buffer_size", 20))
        output = Path(os.path.expanduser(str(self.param("output_dir", "snapshots"))))
        self.output_dir = (
            output if output.is_absolute() else Path(os.environ.get("CORAL_OUTPUT_DIR", ".")) / output
        )
        self.buffers: dict[str, buffering.TopicBuffer] = {}
        self.subscriptions_by_topic: dict[str, Any] = {}
        self.lock = threading.Condition()
        self.count = 0
        self.mode = str(self.param("subscribe", "always"))
        if self.mode not in SUBSCRIBE_MODES:
            raise ValueError(
                f"snapshot: 'subscribe' must be one of {list(SUBSCRIBE_MODES)}, not {self.mode!r}"
            )
        self.request_wait_s = float(self.param("request_wait_s", 5.0))
        self.requests_in_flight = 0
        self.subscribing = threading.Lock()  # one request at a time creates or destroys subscriptions
        types = [t for t in (self.param("types", [""]) or []) if t]
        if types and len(types) != len(self.topics):
            raise ValueError(f"snapshot: 'types' lists {len(types)} type(s) for {len(self.topics)} topic(s)")
        self.types = dict(zip(self.topics, types, strict=False))
        for name in self.types.values():
            message_class(name)  # a bad type name fails at start, not at the first request
        # Until a snapshot was saved, both modes listen from the start: whatever the first snapshot
        # waits for may be sent only once, before its request arrives.
        self.listening_from_start = True
        self.subscribe_all()
        self.create_timer(0.5, self.keep_listening)
        self.create_cancellable_service(Trigger, "~/latest", self.serve_latest)
        self.create_cancellable_service(Trigger, "~/synchronized", self.serve_synchronized)

    def subscribe_all(self) -> None:
        """Subscribes to every configured topic whose type is known (from `types` or the graph)."""
        with self.subscribing:
            self._subscribe_known()

    def _subscribe_known(self) -> None:
        for topic, msgtype in self.types.items():
            if topic not in self.buffers:
                self.subscribe(topic, msgtype)
        self.subscribe_discovered()

    def keep_listening(self) -> None:
        """Timer: subscribes to topics whose type the graph now tells, while the skillset listens
        between requests (always, or with `on_request` until the first snapshot is saved)."""
        with self.subscribing:
            if self.mode == "always" or self.listening_from_start:
                self._subscribe_known()

    def subscribe_discovered(self) -> None:
        """Subscribes to configured topics as soon as the graph tells their type."""
        if len(self.buffers) == len(self.topics):
            return
        types = dict(self.get_topic_names_and_types())
        for topic in self.topics:
            if topic not in self.buffers and types.get(topic):
                self.subscribe(topic, types[topic][0])

    def subscribe(self, topic: str, msgtype: str) -> None:
        """A raw subscription buffering `topic`; a bad type name raises ValueError naming it."""
        cls = message_class(msgtype, topic)
        has_header = next(iter(cls.get_fields_and_field_types()), "") == "header"
        buffer = buffering.TopicBuffer(topic, msgtype, has_header, self.buffer_size)
        subscription = self.create_subscription(
            cls,
            topic,
            lambda raw, b=buffer: self.receive(b, raw),
            QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE),
            raw=True,
            # No QoS event handlers (rclpy's default one logs incompatible QoS): `on_request`
            # destroys subscriptions from a request's thread, and rclpy (Jazzy) aborts the spinning
            # thread when a subscription's event handler is destroyed while it builds its wait set.
            event_callbacks=SubscriptionEventCallbacks(use_default_callbacks=False),
        )
        with self.lock:
            self.buffers[topic] = buffer
            self.subscriptions_by_topic[topic] = subscription
        self.get_logger().info(f"Buffering {topic} ({msgtype})")

    def unsubscribe_all(self) -> None:
        with self.subscribing:
            with self.lock:
                subscriptions = list(self.subscriptions_by_topic.values())
                self.subscriptions_by_topic.clear()
                self.buffers.clear()
            for subscription in subscriptions:
                self.destroy_subscription(subscription)
        self.get_logger().info(f"Stopped buffering {', '.join(self.topics)}")

    def receive(self, buffer: buffering.TopicBuffer, raw: bytes) -> None:
        with self.lock:
            buffer.add(bytes(raw), time.time_ns())
            self.lock.notify_all()

    def _choose(self, synchronized: bool) -> tuple[list[buffering.TopicBuffer], list[buffering.Sample] | str]:
        """The buffers and the samples a snapshot would take now, or why there is none (lock held)."""
        missing = [t for t in self.topics if t not in self.buffers]
        buffers = [self.buffers[t] for t in self.topics if t in self.buffers]
        if missing:
            return buffers, f"topic(s) not seen yet: {', '.join(missing)}"
        chosen = (
            buffering.choose_synchronized(buffers, self.slop_ns)
            if synchronized
            else buffering.choose_latest(buffers)
        )
        return buffers, chosen

    def _wait_and_choose(
        self, synchronized: bool, token: CancelToken
    ) -> tuple[list[buffering.TopicBuffer], list[buffering.Sample] | str]:
        """`on_request`: the snapshot the buffers make now, or else the first one the next messages
        make, subscribing while it waits. Once a snapshot was chosen and no other request still
        waits, the skillset unsubscribes; a first request that found none keeps listening, so its
        retry still sees what arrives in between."""
        with self.lock:
            self.requests_in_flight += 1
        chosen: list[buffering.Sample] | str = ""
        try:
            deadline = time.monotonic() + self.request_wait_s
            while True:
                self.subscribe_all()
                with self.lock:
                    buffers, chosen = self._choose(synchronized)
                    remaining = deadline - time.monotonic()
                    if not isinstance(chosen, str) or remaining <= 0 or token.cancelled:
                        return buffers, chosen
                    # Woken by each message; the timeout also retries topics whose type is unknown.
                    self.lock.wait(min(remaining, 0.1))
        finally:
            with self.lock:
                self.requests_in_flight -= 1
                if not isinstance(chosen, str):
                    self.listening_from_start = False
                release = self.requests_in_flight == 0 and not self.listening_from_start
            if release:
                self.unsubscribe_all()

    def _snapshot(self, response: Any, synchronized: bool, token: CancelToken) -> Any:
        if self.mode == "on_request":
            buffers, chosen = self._wait_and_choose(synchronized, token)
        else:
            with self.lock:
                buffers, chosen = self._choose(synchronized)
        if isinstance(chosen, str):
            response.success, response.message = False, json.dumps({"error": chosen})
            return response
        self.count += 1
        folder = self.output_dir / f"snapshot-{self.count:04d}"
        folder.mkdir(parents=True, exist_ok=True)
        entries = []
        for buffer, sample in zip(buffers, chosen, strict=True):
            file = folder / (buffer.topic.strip("/").replace("/", "__") + ".cdr")
            file.write_bytes(sample.raw)
            entries.append(
                {
                    "topic": buffer.topic,
                    "type": buffer.msgtype,
                    "stamp_ns": sample.stamp_ns,
                    "file": file.name,
                }
            )
        (folder / "snapshot.json").write_text(
            json.dumps({"synchronized": synchronized, "messages": entries}, indent=2)
        )
        response.success = True
        response.message = json.dumps(
            {"path": str(folder), "stamps": [e["stamp_ns"] for e in entries], "topics": self.topics}
        )
        self.get_logger().info(f"Saved snapshot {folder}")
        return response

    def serve_latest(self, request: Any, response: Any, token: CancelToken) -> Any:
        return self._snapshot(response, False, token)

    def serve_synchronized(self, request: Any, response: Any, token: CancelToken) -> Any:
        return self._snapshot(response, True, token)


def message_class(msgtype: str, topic: str = "") -> Any:
    """`sensor_msgs/msg/PointCloud2` -> its class; a bad name raises ValueError naming it."""
    try:
        package, kind, name = msgtype.split("/")
        return getattr(importlib.import_module(f"{package}.{kind}"), name)
    except (ValueError, ImportError, AttributeError):
        where = f" for {topic}" if topic else ""
        raise ValueError(f"snapshot: unknown message type {msgtype!r}{where}") from None
