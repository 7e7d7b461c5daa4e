"""Behaviors the SLAM skillset exports; executors import this module from the plugin location.

Each action calls one service of the skillset (`~/...` = the exporting node) and never blocks the
tick; conditions read the skillset's status topic. Only `coral` and standard ROS interfaces are
imported, as the plugin rules require. Responses of `std_srvs/Trigger` services carry a small JSON
object in `message`.
"""

from __future__ import annotations

from typing import Any

from coral.sdk.behaviors import ServiceBehavior
from coral.sdk.calls import LatestMessage, ServiceCall
from coral.sdk.declaring import behavior, input_port, output_port
from coral_core import parsing
from coral_core.bt import Status
from coral_core.bt.leaves import ConditionNode, StatefulAction
from nav_msgs.srv import LoadMap as LoadMapSrv
from std_msgs.msg import Empty, String
from std_srvs.srv import SetBool, Trigger


def optional_output(node: Any, port: str, value: Any) -> None:
    """Writes an output port only when the tree wired it: BT.CPP ignores unwired outputs, so do we."""
    if getattr(node, "ports", {}).get(port) is not None:
        node.set_output(port, value)


def _payload(response: Any) -> dict[str, Any]:
    try:
        value = parsing.load_json(response.message or "{}")
    except ValueError:
        return {"error": response.message}
    return value if isinstance(value, dict) else {}


def _explain(node: Any, response: Any) -> Status:
    node.feedback_message = _payload(response).get("error", response.message)
    return Status.FAILURE


@behavior(description="Starts registering incoming scans (queued since the skillset started)")
class EnableLocalization(ServiceBehavior):
    """SUCCESS once the skillset accepts scans; FAILURE if it refuses or does not answer."""

    SERVICE_TYPE = SetBool
    SERVICE_NAME = "~/set_localization"
    TIMEOUT_S = 15.0  # often the mission's first call: it includes discovering the skillset
    PORTS: list[Any] = []

    def make_request(self) -> Any:
        return SetBool.Request(data=True)

    def on_response(self, response: Any) -> Status:
        return Status.SUCCESS if response.success else _explain(self, response)


@behavior(description="Stops registering scans; the map and trajectory are kept")
class DisableLocalization(EnableLocalization):
    """SUCCESS once the skillset stopped accepting scans."""

    def make_request(self) -> Any:
        return SetBool.Request(data=False)


@behavior(description="Registers the next queued scan with KISS-ICP")
class ProcessScan(ServiceBehavior):
    """SUCCESS with the new pose; FAILURE when no scan came in time or the scan was unusable
    (non-finite points are dropped first, so one bad scan costs one failure, not the skillset)."""

    SERVICE_TYPE = Trigger
    SERVICE_NAME = "~/process_scan"
    TIMEOUT_S = 10.0
    PORTS = [
        output_port("scans_processed", "int", description="Scans registered so far"),
        output_port("pose", "string", description="x;y;z;yaw of the sensor in the map frame"),
    ]

    def on_response(self, response: Any) -> Status:
        if not response.success:
            return _explain(self, response)
        payload = _payload(response)
        optional_output(self, "scans_processed", int(payload.get("scans", 0)))
        optional_output(self, "pose", ";".join(f"{v:.3f}" for v in payload.get("pose", [])))
        self.feedback_message = f"scan {payload.get('scans')}"
        return Status.SUCCESS


@behavior(description="Distance and rotation mapped since the last time the targets were reached")
class GetMappingDisplacement(StatefulAction):
    """SUCCESS when the sensor moved at least `linear_target` metres or turned `angular_target`
    radians since the last success (which then restarts the count); FAILURE otherwise."""

    SIGNALS_WAKE_UP = True  # RUNNING only while its ServiceCall waits
    DISPLACEMENT = "~/displacement"
    MARK = "~/mark_displacement"
    CALLS = ((Trigger, DISPLACEMENT), (Trigger, MARK))

    PORTS = [
        input_port("linear_target", "double", default=10.0, description="Metres"),
        input_port("angular_target", "double", default=3.14, description="Radians"),
        output_port("linear", "double", description="Metres moved since the last mark"),
        output_port("angular", "double", description="Radians turned since the last mark"),
    ]

    def on_start(self) -> Status:
        self.reached = False
        self.call = ServiceCall(self, Trigger, self.DISPLACEMENT, timeout_s=5.0)
        return self._step(self.call.send(Trigger.Request()))

    def on_running(self) -> Status:
        return self._step(self.call.poll())

    def _step(self, status: Status) -> Status:
        if status != Status.SUCCESS:
            return status
        if self.reached:  # the mark request finished
            return Status.SUCCESS
        payload = _payload(self.call.response)
        linear, angular = float(payload.get("linear", 0.0)), float(payload.get("angular", 0.0))
        optional_output(self, "linear", linear)
        optional_output(self, "angular", angular)
        self.feedback_message = f"{linear:.2f} m, {angular:.2f} rad"
        if linear < float(self.get_input("linear_target")) and angular < float(
            self.get_input("angular_target")
        ):
            return Status.FAILURE
        self.reached = True
        self.call = ServiceCall(self, Trigger, self.MARK, timeout_s=5.0)
        return self._step(self.call.send(Trigger.Request()))

    def on_halted(self) -> None:
        self.call.cancel()


@behavior(description="Writes the global map (PLY) and the trajectory (CSV) to the skillset's map_path")
class SaveMap(ServiceBehavior):
    """SUCCESS once the files are written; FAILURE when the path cannot be written."""

    SERVICE_TYPE = Trigger
    SERVICE_NAME = "~/save_map"
    TIMEOUT_S = 30.0
    PORTS = [
        output_port("path", "string", description="Where the map was written"),
        output_port("points", "int", description="Points in the saved map"),
    ]

    def on_response(self, response: Any) -> Status:
        if not response.success:
            return _explain(self, response)
        payload = _payload(response)
        optional_output(self, "path", str(payload.get("path", "")))
        optional_output(self, "points", int(payload.get("points", 0)))
        return Status.SUCCESS


@behavior(description="Seeds the SLAM map with a saved PLY map, to localise against it")
class LoadMap(ServiceBehavior):
    """SUCCESS once the map is loaded; FAILURE when the file is missing or not a map."""

    SERVICE_TYPE = LoadMapSrv
    SERVICE_NAME = "~/load_map"
    TIMEOUT_S = 30.0
    PORTS = [input_port("path", "string", description="PLY file written by SaveMap")]

    def make_request(self) -> Any:
        return LoadMapSrv.Request(map_url=str(self.get_input("path") or ""))

    def on_response(self, response: Any) -> Status:
        if response.result != LoadMapSrv.Response.RESULT_SUCCESS:
            self.feedback_message = f"load_map result {response.result}"
            return Status.FAILURE
        return Status.SUCCESS


@behavior(description="Size of the current (local) and global maps")
class GetCurrentMap(ServiceBehavior):
    """SUCCESS with the point counts of the map KISS-ICP registers against and of the global map."""

    SERVICE_TYPE = Trigger
    SERVICE_NAME = "~/map_info"
    PORTS = [
        output_port("local_points", "int", description="Points in the local map"),
        output_port("global_points", "int", description="Points in the global map"),
    ]

    def on_response(self, response: Any) -> Status:
        payload = _payload(response)
        optional_output(self, "local_points", int(payload.get("local_points", 0)))
        optional_output(self, "global_points", int(payload.get("global_points", 0)))
        return Status.SUCCESS


@behavior(description="True when the data source has ended and every queued scan was processed")
class IsDataExhausted(ConditionNode):
    """SUCCESS when the skillset reports end of data with an empty queue; FAILURE otherwise."""

    PORTS: list[Any] = []

    def tick(self) -> Status:
        if getattr(self, "status_topic", None) is None:
            self.status_topic = LatestMessage(self, String, "~/status")
        message = self.status_topic.get()
        if message is None:
            return Status.FAILURE
        try:
            status = parsing.load_json(message.data)
        except ValueError:
            return Status.FAILURE
        self.feedback_message = f"{status.get('processed')} processed, {status.get('queued')} queued"
        return Status.SUCCESS if status.get("exhausted") else Status.FAILURE


@behavior(description="True once any message arrived on the stop topic (std_msgs/Empty)")
class IsStopRequested(ConditionNode):
    """SUCCESS after a stop request was published on `topic`; FAILURE before."""

    PORTS = [input_port("topic", "string", default="/slam/stop", description="std_msgs/Empty topic")]

    def tick(self) -> Status:
        if getattr(self, "stop_topic", None) is None:
            self.stop_topic = LatestMessage(self, Empty, str(self.get_input("topic")))
        return Status.SUCCESS if self.stop_topic.get() is not None else Status.FAILURE
