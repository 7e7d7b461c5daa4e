"""Behaviors the snapshot skillset exports; executors import this module from the plugin location."""

from __future__ import annotations

from typing import Any

from coral.sdk.calls import ServiceCall
from coral.sdk.declaring import behavior, input_port, output_port
from coral_core import parsing
from coral_core.bt import Status
from coral_core.bt.leaves import StatefulAction
from std_srvs.srv import Trigger

SERVICES = {"latest": "~/latest", "synchronized": "~/synchronized"}


@behavior(description="Saves the newest (or time-synchronised) message of every configured topic")
class TakeSnapshot(StatefulAction):
    """SUCCESS with the snapshot folder in `snapshot`; FAILURE while a topic has no data yet (or, in
    `synchronized` mode, no set of messages lies within the skillset's slop)."""

    SIGNALS_WAKE_UP = True  # RUNNING only while its ServiceCall waits
    CALLS = tuple((Trigger, service) for service in SERVICES.values())

    PORTS = [
        input_port("mode", "string", default="latest", description="latest | synchronized"),
        output_port("snapshot", "string", description="Folder holding the saved messages"),
        output_port("stamp", "string", description="Header stamp (ns) of the first topic's message"),
    ]

    def on_start(self) -> Status:
        mode = str(self.get_input("mode"))
        if mode not in SERVICES:
            self.feedback_message = f"mode must be one of {sorted(SERVICES)}, not {mode!r}"
            return Status.FAILURE
        self.call = ServiceCall(self, Trigger, SERVICES[mode], timeout_s=10.0)
        return self._step(self.call.send(Trigger.Request()))

    def on_running(self) -> Status:
        return self._step(self.call.poll())

    def _step(self, status: Status) -> Status:
        if status != Status.SUCCESS:
            return status
        response: Any = self.call.response
        try:
            payload = parsing.load_json(response.message or "{}")
        except ValueError:
            payload = {"error": response.message}
        if not response.success:
            self.feedback_message = str(payload.get("error", response.message))
            return Status.FAILURE
        self.set_output("snapshot", str(payload.get("path", "")))
        stamps = payload.get("stamps") or [0]
        self.set_output("stamp", str(stamps[0]))
        return Status.SUCCESS

    def on_halted(self) -> None:
        self.call.cancel()
