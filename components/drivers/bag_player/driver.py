"""The bag player driver's ROS 2 node: republishes a bag's messages, then stops with exit code 0.

Parameters (node `bag_player`): bag (path; when empty, $CORAL_BAG), rate (1.0 = recorded timing,
2.0 twice as fast, 0 = as fast as possible), topics (list; empty = all), wait_for_subscribers
(how many subscribers the first topic needs before playing starts, every other topic needing one,
so skillsets that start after the driver miss nothing), wait_timeout_s, done_topic
(std_msgs/String, latched: JSON {"done": true, "published": {topic: count}} once everything was published).
Messages are forwarded as raw CDR bytes, never deserialised.
"""

from __future__ import annotations

import importlib
import json
import os
import threading
import time
from pathlib import Path
from typing import Any

from coral.sdk import Driver
from coral_drivers.bag_player import playing
from rclpy.duration import Duration
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import String


def message_class(msgtype: str) -> Any:
    """`sensor_msgs/msg/PointCloud2` -> the rclpy message class."""
    package, kind, name = msgtype.split("/")
    return getattr(importlib.import_module(f"{package}.{kind}"), name)


class BagPlayer(Driver):
    NAME = "bag_player"
    # A bag played faster than recorded is one burst of its largest messages (docs/architecture.md,
    # "Where the SLAM mission's CPU goes").
    LARGE_MESSAGES = True

    def on_start(self) -> None:
        bag = str(self.param("bag", "")) or os.environ.get("CORAL_BAG", "")
        if not bag:
            raise ValueError("bag_player: set the 'bag' parameter or the CORAL_BAG environment variable")
        self.bag = Path(os.path.expanduser(bag))
        self.rate = float(self.param("rate", 1.0))
        wanted = [t for t in (self.param("topics", [""]) or []) if t]
        infos = playing.read_topics(self.bag)
        known = {info.name: info for info in infos}
        missing = sorted(set(wanted) - set(known))
        if missing:
            raise ValueError(f"{self.bag}: no topic(s) {missing}; the bag has {sorted(known)}")
        self.topics = wanted or sorted(known)
        self.streams: dict[str, Any] = {}
        for topic in self.topics:
            self.streams[topic] = self.create_stream(
                message_class(known[topic].msgtype), topic, depth=int(self.param("depth", 1000))
            )
        latched = QoSProfile(
            depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
        )
        self.done_publisher = self.create_publisher(
            String, str(self.param("done_topic", "/bag_player/done")), latched
        )
        self.done_publisher.publish(String(data=json.dumps({"done": False, "published": {}})))
        self.wait_for = int(self.param("wait_for_subscribers", 1))
        self.wait_timeout_s = float(self.param("wait_timeout_s", 60.0))
        self.stop_playing = threading.Event()
        total = sum(known[t].count for t in self.topics)
        self.get_logger().info(
            f"Playing {total} message(s) on {self.topics} from {self.bag} at rate {self.rate:g}"
        )
        self.thread = threading.Thread(target=self.play, name="bag-player", daemon=True)
        self.thread.start()

    def wait_for_subscribers(self) -> bool:
        """The first topic needs `wait_for_subscribers` subscribers, every other topic at least one."""
        deadline = time.monotonic() + self.wait_timeout_s
        needed = {topic: (self.wait_for if i == 0 else 1) for i, topic in enumerate(self.topics)}
        while any(self.streams[t].get_subscription_count() < n for t, n in needed.items()):
            if self.stop_playing.wait(0.05) or time.monotonic() > deadline:
                return False
        return True

    def play(self) -> None:
        if self.wait_for > 0:
            waited = time.monotonic()
            if not self.wait_for_subscribers():
                if not self.stop_playing.is_set():
                    self.get_logger().error(
                        f"No subscriber on {self.topics[0]} within {self.wait_timeout_s:g} s; not playing"
                    )
                    self.request_stop(1)
                return
            # Says when the bag started, so a late start shows whether the player waited for its
            # subscribers (and how long) or for something else.
            self.get_logger().info(
                f"{self.streams[self.topics[0]].get_subscription_count()} subscriber(s) on {self.topics[0]} "
                f"after {time.monotonic() - waited:.2f} s: playing"
            )
        try:
            report = playing.play(
                playing.iterate(self.bag, self.topics),
                lambda topic, _msgtype, raw: self.streams[topic].publish(raw),
                rate=self.rate,
                stop=self.stop_playing,
            )
        except playing.BagError as err:
            self.get_logger().error(str(err))
            self.request_stop(1)
            return
        if report.stopped_early:
            return
        # Subscribers count what they received against `published`: messages of different
        # topics are not ordered, so the done signal can overtake the last scan.
        self.done_publisher.publish(String(data=json.dumps({"done": True, "published": report.per_topic})))
        # Reliable delivery of the tail before the process goes away.
        for publisher in [*self.streams.values(), self.done_publisher]:
            publisher.wait_for_all_acked(Duration(seconds=10))
        self.get_logger().info(f"Played {report.messages} message(s) in {report.duration_s:.1f} s")
        self.request_stop(0)

    def on_stop(self) -> None:
        self.stop_playing.set()
