"""Generic behaviors built on `coral.sdk.calls`: subclass them in a skillset's behavior module.

`ServiceBehavior` is one stateful action parametrized by service type and name, the pattern a
skillset uses for any asynchronous skill backed by a ROS service.
"""

from __future__ import annotations

from typing import Any, ClassVar

from coral_core.bt import Status
from coral_core.bt.leaves import StatefulAction

from coral.sdk import calls


class ServiceBehavior(StatefulAction):
    """Calls `SERVICE_NAME` (`SERVICE_TYPE`) and waits for its response without blocking the tick.

    RUNNING while the request is in flight; SUCCESS or FAILURE as `on_response` decides once the
    response arrives; FAILURE when no response comes within `TIMEOUT_S` or the skillset stopped.
    Halting the behavior cancels the request (the skillset's `CancelToken` is set).

    Override `make_request` (read input ports there) and `on_response` (write output ports).
    `SERVICE_NAME` may start with `~/` to name a service of the exporting skillset's node.
    """

    SIGNALS_WAKE_UP = True  # the response and the call's deadline wake the tree
    SERVICE_TYPE: ClassVar[Any] = None
    SERVICE_NAME: ClassVar[str] = ""
    TIMEOUT_S: ClassVar[float] = 5.0
    # The services this behavior calls, whose clients the executor opens with the tree
    # (`calls.open_clients`); derived from SERVICE_TYPE and SERVICE_NAME unless a subclass sets it.
    CALLS: ClassVar[tuple[tuple[Any, str], ...]] = ()

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if "CALLS" not in cls.__dict__ and cls.SERVICE_TYPE is not None and cls.SERVICE_NAME:
            cls.CALLS = ((cls.SERVICE_TYPE, cls.SERVICE_NAME),)

    def make_request(self) -> Any:
        return self.SERVICE_TYPE.Request()

    def on_response(self, response: Any) -> Status:
        return Status.SUCCESS

    def on_start(self) -> Status:
        self.call = calls.ServiceCall(self, self.SERVICE_TYPE, self.SERVICE_NAME, timeout_s=self.TIMEOUT_S)
        return self._after(self.call.send(self.make_request()))

    def on_running(self) -> Status:
        return self._after(self.call.poll())

    def _after(self, status: Status) -> Status:
        if status != Status.SUCCESS:
            return status
        result = self.on_response(self.call.response)
        if result == Status.FAILURE:
            # The skillset answered and refused: its reason (the feedback `on_response` left) is
            # the failure's message in the tree status.
            reason = getattr(self, "feedback_message", "") or f"{self.call.service} refused the request"
            calls.note_refusal(self, reason)
        return result

    def on_halted(self) -> None:
        call = getattr(self, "call", None)
        if call is not None:
            call.cancel()
