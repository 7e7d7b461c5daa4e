"""The example skillset's ROS side: a counter service that can be slowed down and cancelled.

Started by `python -m coral_skillsets.examples` or `python -m coral.sdk.run
coral_skillsets.examples.skillset:ExampleSkillset`; tests and the call benchmark use it.
"""

from __future__ import annotations

import threading
import time

from coral.sdk import CancelToken, Skillset
from coral_skillsets.examples import behaviors
from rclpy.qos import DurabilityPolicy, QoSProfile
from std_msgs.msg import Int64
from std_srvs.srv import Trigger


class ExampleSkillset(Skillset):
    """Serves `~/count`: waits `work_delay_s` (parameter, default 0), then increments a counter,
    which it also publishes (latched) on `~/count_state`."""

    NAME = "examples"
    BEHAVIORS = [behaviors.Greet, behaviors.Count, behaviors.IsAtLeast, behaviors.WaitForCount]

    def on_start(self) -> None:
        self.work_delay_s = float(self.param("work_delay_s", 0.0))
        self.count = 0
        self.count_lock = threading.Lock()
        # Latched, so a behavior subscribing later still sees the current count.
        latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.count_state = self.create_publisher(Int64, "~/count_state", latched)
        self.create_cancellable_service(Trigger, "~/count", self.serve_count)

    def serve_count(
        self, request: Trigger.Request, response: Trigger.Response, token: CancelToken
    ) -> Trigger.Response:
        started = time.monotonic()
        if self.work_delay_s > 0:
            # Only slow requests are logged: tests wait for this line; the benchmark's fast path stays quiet.
            self.get_logger().info(f"Count request started, working for {self.work_delay_s:g} s")
        if self.work_delay_s > 0 and token.wait(self.work_delay_s):
            self.get_logger().info(f"Count request cancelled after {time.monotonic() - started:.2f} s")
            response.success = False
            response.message = "cancelled"
            return response
        with self.count_lock:
            self.count += 1
            response.message = str(self.count)
            self.count_state.publish(Int64(data=self.count))
        response.success = True
        return response
