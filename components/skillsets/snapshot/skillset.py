"""The snapshot skillset's ROS 2 node: buffers configured topics raw and saves snapshots on request.

Run with `python -m coral_skillsets.snapshot --plugins DIR [--params FILE]`. Parameters (node
`snapshot`): topics (list), types (list beside topics, e.g. sensor_msgs/msg/PointCloud2: subscribed
at start; without it, types are taken from the ROS graph once the topics appear), slop_s
(synchronisation tolerance), buffer_size (messages kept per topic), output_dir (relative paths
resolve against $CORAL_OUTPUT_DIR). Messages are kept as raw CDR, so buffering a LiDAR topic costs
no deserialisation. A snapshot is a folder with one `.cdr` file per topic and `snapshot.json`.
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
from rclpy.qos import QoSProfile, ReliabilityPolicy
from std_srvs.srv import Trigger


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
        self.lock = threading.Lock()
        self.count = 0
        types = [t for t in (self.param("types", [""]) or []) if t]
        if types and len(types) != len(self.topics):
            raise ValueError(f"snapshot: 'types' lists {len(types)} type(s) for {len(self.topics)} topic(s)")
        for topic, msgtype in zip(self.topics, types, strict=False):
            self.subscribe(topic, msgtype)
        self.create_timer(0.5, self.subscribe_discovered)
        self.create_cancellable_service(Trigger, "~/latest", self.serve_latest)
        self.create_cancellable_service(Trigger, "~/synchronized", self.serve_synchronized)

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
        try:
            package, kind, name = msgtype.split("/")
            cls = getattr(importlib.import_module(f"{package}.{kind}"), name)
        except (ValueError, ImportError, AttributeError):
            raise ValueError(f"snapshot: unknown message type {msgtype!r} for {topic}") from None
        has_header = next(iter(cls.get_fields_and_field_types()), "") == "header"
        buffer = buffering.TopicBuffer(topic, msgtype, has_header, self.buffer_size)
        self.create_subscription(
            cls,
            topic,
            lambda raw, b=buffer: self.receive(b, raw),
            QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE),
            raw=True,
        )
        with self.lock:
            self.buffers[topic] = buffer
        self.get_logger().info(f"Buffering {topic} ({msgtype})")

    def receive(self, buffer: buffering.TopicBuffer, raw: bytes) -> None:
        with self.lock:
            buffer.add(bytes(raw), time.time_ns())

    def _snapshot(self, response: Any, synchronized: bool) -> Any:
        with self.lock:
            missing = [t for t in self.topics if t not in self.buffers]
            buffers = [self.buffers[t] for t in self.topics if t in self.buffers]
            chosen = (
                f"topic(s) not seen yet: {', '.join(missing)}"
                if missing
                else buffering.choose_synchronized(buffers, self.slop_ns)
                if synchronized
                else buffering.choose_latest(buffers)
            )
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
        return self._snapshot(response, synchronized=False)

    def serve_synchronized(self, request: Any, response: Any, token: CancelToken) -> Any:
        return self._snapshot(response, synchronized=True)
