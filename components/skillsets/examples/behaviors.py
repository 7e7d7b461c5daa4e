"""Behaviors exported by the example skillset; executors import this file from the plugin location.

It imports only `coral`, ROS interface packages and the standard library, because it runs inside
executors that do not have the skillset's package installed.
"""

from __future__ import annotations

from coral.sdk import calls
from coral.sdk.behaviors import ServiceBehavior
from coral.sdk.declaring import behavior, input_port, output_port
from coral_core.bt import Status
from coral_core.bt.leaves import ConditionNode, StatefulAction, SyncAction
from std_msgs.msg import Int64
from std_srvs.srv import Trigger


@behavior(description="Writes a greeting for `who` to `greeting`")
class Greet(SyncAction):
    """Synchronous action: SUCCESS after writing the greeting; FAILURE when `who` is empty."""

    PORTS = [
        input_port("who", "string", default="world", description="Who to greet"),
        output_port("greeting", "string", description="The greeting"),
    ]

    def tick(self) -> Status:
        name = self.get_input("who")
        if not name:
            return Status.FAILURE
        self.set_output("greeting", f"Hello, {name}!")
        return Status.SUCCESS


@behavior(description="Asks the skillset to count once; outputs the new count")
class Count(ServiceBehavior):
    """Asynchronous action backed by the skillset's `~/count` service (std_srvs/Trigger).

    RUNNING while the skillset works (its `work_delay_s` parameter), SUCCESS with `count` set,
    FAILURE on timeout or when the skillset stopped. Halting cancels the request.
    """

    SERVICE_TYPE = Trigger
    SERVICE_NAME = "~/count"
    TIMEOUT_S = 5.0
    PORTS = [output_port("count", "int", description="The skillset's counter after this call")]

    def on_response(self, response: Trigger.Response) -> Status:
        if not response.success:
            return Status.FAILURE
        self.set_output("count", int(response.message))
        return Status.SUCCESS


@behavior(description="True when `value` >= `threshold`")
class IsAtLeast(ConditionNode):
    """Condition: SUCCESS when `value` is at least `threshold`, else FAILURE."""

    PORTS = [
        input_port("value", "int", description="Value to test"),
        input_port("threshold", "int", default=1, description="Smallest accepted value"),
    ]

    def tick(self) -> Status:
        value = self.get_input("value")
        threshold = self.get_input("threshold")
        return Status.SUCCESS if value is not None and value >= threshold else Status.FAILURE


@behavior(description="Waits until the skillset's published count reaches `threshold`")
class WaitForCount(StatefulAction):
    """Asynchronous action on a topic: RUNNING until the skillset's latched `~/count_state`
    reaches `threshold` (SUCCESS), FAILURE after `timeout_ms` or when the skillset stopped."""

    PORTS = [
        input_port("threshold", "int", default=1, description="Count to wait for"),
        input_port("timeout_ms", "int", default=5000, description="Give up after this long"),
    ]

    def on_start(self) -> Status:
        threshold = self.get_input("threshold")
        self.wait = calls.TopicWait(
            self,
            Int64,
            "~/count_state",
            accept=lambda message: message.data >= threshold,
            timeout_s=self.get_input("timeout_ms") / 1000.0,
            latched=True,
        )
        return self.wait.start()

    def on_running(self) -> Status:
        return self.wait.poll()
