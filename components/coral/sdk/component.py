"""Base classes for Coral components: `Skillset` and `Driver`, each a ROS 2 node.

A component subclass declares what it exports (`BEHAVIORS`, `EXPORT_MODULES`,
`INTERFACE_PACKAGES`) and creates its ROS interfaces in `on_start`. `coral.sdk.running` builds the
node, exports the plugin, publishes heartbeats and spins until SIGINT/SIGTERM or `request_stop`.
"""

from __future__ import annotations

import os
import re
import threading
import uuid
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, ClassVar

from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from std_msgs.msg import String

from coral.plugins import manifest as manifests
from coral.sdk import topics


def default_component_name(cls: type) -> str:
    """`ExampleSkillset` -> `example_skillset`: a valid ROS node name derived from the class name."""
    return re.sub(r"(?<!^)(?=[A-Z])", "_", cls.__name__).lower()


class CancelToken:
    """Set when the executor that sent a request halted its behavior; handlers poll or wait on it."""

    def __init__(self) -> None:
        self._event = threading.Event()

    @property
    def cancelled(self) -> bool:
        return self._event.is_set()

    def cancel(self) -> None:
        self._event.set()

    def wait(self, timeout_s: float) -> bool:
        """Waits up to `timeout_s`; True as soon as the request is cancelled (use instead of sleep)."""
        return self._event.wait(timeout_s)


CancellableHandler = Callable[[Any, Any, CancelToken], Any]


class Component(Node):
    """A Coral component: a ROS 2 node that exports behaviors and interface packages.

    Class attributes to set in subclasses:
        NAME: component name (also the node name); defaults to the class name in snake case.
        BEHAVIORS: behavior classes (`coral_core.bt.leaves` subclasses) this component exports.
        EXPORT_MODULES: extra modules (dotted names) the behavior modules import relatively.
        INTERFACE_PACKAGES: interface packages (import names or folders) for the executor's path.
        LARGE_MESSAGES: the component publishes bursts of messages of hundreds of kilobytes
            (scans, images), so its process gets DDS's large shared-memory segment
            (`coral.sdk.dds`), 17 MB of `/dev/shm` from the start: set it where the data is.
    """

    KIND: ClassVar[str] = "skillset"
    NAME: ClassVar[str | None] = None
    BEHAVIORS: ClassVar[Sequence[type]] = ()
    EXPORT_MODULES: ClassVar[Sequence[str]] = ()
    INTERFACE_PACKAGES: ClassVar[Sequence[str]] = ()
    LARGE_MESSAGES: ClassVar[bool] = False

    def __init__(
        self,
        *,
        name: str | None = None,
        namespace: str | None = None,
        params_file: Path | None = None,
        **node_kwargs: Any,
    ) -> None:
        component_name = name or self.NAME or default_component_name(type(self))
        if not manifests.COMPONENT_NAME_RE.match(component_name):
            raise ValueError(
                f"component name {component_name!r} must match {manifests.COMPONENT_NAME_RE.pattern}"
            )
        cli_args = ["--ros-args", "--params-file", str(params_file)] if params_file else None
        super().__init__(
            component_name,
            namespace=namespace or "",
            cli_args=cli_args,
            automatically_declare_parameters_from_overrides=True,
            **node_kwargs,
        )
        self.component_name = component_name
        self.instance_id = uuid.uuid4().hex[:12]
        self.exit_code: int | None = None
        self.stop_requested = threading.Event()
        self._cancel_group = ReentrantCallbackGroup()
        self._inflight: dict[str, set[CancelToken]] = {}
        self._inflight_lock = threading.Lock()
        self._cancel_subscription: Any = None

    # Lifecycle hooks for subclasses.
    def on_start(self) -> None:
        """Create services, publishers and timers here; called once, before the plugin is exported."""

    def on_stop(self) -> None:
        """Release resources; called once on SIGINT/SIGTERM or after `request_stop`."""

    # Helpers.
    def param(self, name: str, default: Any = None) -> Any:
        """A parameter's value, declaring it with `default` when the parameters file does not set it."""
        if not self.has_parameter(name):
            self.declare_parameter(name, default)
        return self.get_parameter(name).value

    def request_stop(self, exit_code: int = 0) -> None:
        """Ends the component's process with `exit_code` (a transient driver calls this when done)."""
        self.exit_code = exit_code
        self.stop_requested.set()

    @property
    def component_ref(self) -> manifests.ComponentRef:
        return manifests.ComponentRef(
            name=self.component_name,
            kind=self.KIND,  # type: ignore[arg-type]
            node_name=self.get_name(),
            namespace=self.get_namespace(),
        )

    def heartbeat(self, state: str) -> topics.Heartbeat:
        return topics.Heartbeat(self.component_name, self.KIND, state, os.getpid(), self.instance_id)

    def create_cancellable_service(self, srv_type: Any, name: str, handler: CancellableHandler) -> Any:
        """A service whose handler gets a `CancelToken`, set when the calling behavior is halted.

        Handlers run on their own thread, so a long request does not block other callbacks; they
        should return promptly (any response) once the token is cancelled.
        """
        if self._cancel_subscription is None:
            self._cancel_subscription = self.create_subscription(
                String,
                topics.CANCEL_TOPIC,
                self._on_cancel,
                QoSProfile(depth=50, reliability=ReliabilityPolicy.RELIABLE),
                callback_group=self._cancel_group,
            )
        service: Any = None

        def serve(request: Any, response: Any) -> Any:
            token = CancelToken()
            key = service.service_name
            with self._inflight_lock:
                self._inflight.setdefault(key, set()).add(token)
            try:
                return handler(request, response, token)
            finally:
                with self._inflight_lock:
                    self._inflight[key].discard(token)

        service = self.create_service(srv_type, name, serve, callback_group=self._cancel_group)
        return service

    def _on_cancel(self, message: String) -> None:
        request = topics.CancelRequest.decode(message.data)
        if request is None:
            return
        with self._inflight_lock:
            tokens = list(self._inflight.get(request.service, ()))
        for token in tokens:
            token.cancel()
        if tokens:
            self.get_logger().info(
                f"Cancelled {len(tokens)} request(s) on {request.service} for {request.requester}"
            )


class Skillset(Component):
    """A component that runs ROS 2 nodes and exports the behaviors that use them."""

    KIND: ClassVar[str] = "skillset"


class Driver(Component):
    """A component that wraps hardware (or a recording) and publishes data streams for skillsets."""

    KIND: ClassVar[str] = "driver"

    def create_stream(self, msg_type: Any, topic: str, *, depth: int = 10, reliable: bool = True) -> Any:
        """A publisher for a data stream; best effort suits high-rate sensors whose old samples are stale."""
        reliability = ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT
        return self.create_publisher(msg_type, topic, QoSProfile(depth=depth, reliability=reliability))
