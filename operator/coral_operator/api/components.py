"""The component model shared by drivers, skillsets and executors of a CoralSystem.

Used by `api.system` (the user's spec), `api.instance` (the per-robot copy) and
`planning.pods` (which turns one component into one pod).
"""

from __future__ import annotations

import re
from typing import Annotated, Literal

from coral_core.wire import CamelModel
from pydantic import Field, field_validator

DNS_LABEL = r"^[a-z0-9]([-a-z0-9]*[a-z0-9])?$"
Quantity = int | Annotated[str, Field(max_length=64)]
# Everything in a component is copied into every robot's CoralInstance and pods, so each string is
# bounded at admission; what the strings add up to across robots is the operator's to bound
# (`planning.budgets`, issue 47).
MAX_ENV_VALUE_LENGTH = 4096
MAX_ARGUMENT_LENGTH = 4096
Argument = Annotated[str, Field(max_length=MAX_ARGUMENT_LENGTH)]


class EnvVar(CamelModel):
    """One environment variable set in the component's container."""

    name: str = Field(min_length=1, max_length=253)
    """Variable name."""
    value: str = Field(default="", max_length=MAX_ENV_VALUE_LENGTH)
    """Variable value (literal; parameters belong in the system's parameters file). At most 4096
    characters: it is copied to every robot."""


# A Kubernetes quantity as a string (`250m`, `1Gi`, `1e3`); whole numbers may be given as integers.
QUANTITY = r"^[+]?([0-9]+([.][0-9]*)?|[.][0-9]+)(Ki|Mi|Gi|Ti|Pi|Ei|[numkMGTPE]|[eE][+-]?[0-9]+)?$"
QUANTITY_SYNTAX = "must be quantities such as 250m, 256Mi or 2"


def _check_quantities(values: dict[str, Quantity]) -> dict[str, Quantity]:
    for name, value in values.items():
        if (
            isinstance(value, int)
            and value < 0
            or isinstance(value, str)
            and not re.fullmatch(QUANTITY, value)
        ):
            raise ValueError(f"{name}: {value!r} {QUANTITY_SYNTAX}")
    return values


class Resources(CamelModel):
    """Compute resources of the component's container, as in a pod's container spec."""

    # Checked here (the operator stalls the system naming the field) rather than by CEL: a regex
    # over map values costs more than the API server's CEL budget allows.

    requests: dict[str, Quantity] = Field(default_factory=dict, max_length=16)
    """Minimum resources, for example `cpu: 250m`, `memory: 256Mi`."""
    limits: dict[str, Quantity] = Field(default_factory=dict, max_length=16)
    """Maximum resources, for example `memory: 1Gi`."""

    _requests_syntax = field_validator("requests")(_check_quantities)
    _limits_syntax = field_validator("limits")(_check_quantities)


class DeviceMount(CamelModel):
    """A device file of the robot passed into the container (for example a serial port or camera)."""

    host_path: str = Field(pattern=r"^/", max_length=1024)
    """Absolute path of the device on the robot, for example `/dev/ttyUSB0`."""
    container_path: str | None = Field(default=None, pattern=r"^/", max_length=1024)
    """Path inside the container; the host path when omitted."""


class HostPathMount(CamelModel):
    """A folder or file of the robot mounted into the container."""

    host_path: str = Field(pattern=r"^/", max_length=1024)
    """Absolute path on the robot."""
    mount_path: str = Field(pattern=r"^/", max_length=1024)
    """Absolute path inside the container."""
    read_only: bool = True
    """Mount read-only (the default) or read-write."""


class Readiness(CamelModel):
    """When the component counts as ready, which gates the next startup stage."""

    exec: list[Argument] = Field(default_factory=list, max_length=32)
    """Command run in the container; ready when it exits 0. Empty: see `pluginMarker`."""
    plugin_marker: bool | None = None
    """Ready when the component's `ready` marker exists in the plugin folder (default for skillsets)."""
    initial_delay_seconds: int = Field(default=0, ge=0, le=3600)
    """Seconds before the first check."""
    period_seconds: int = Field(default=2, ge=1, le=300)
    """Seconds between checks."""
    failure_threshold: int = Field(default=3, ge=1, le=100)
    """Consecutive failed checks before the component counts as not ready."""


class Component(CamelModel):
    """One containerized Coral component: a driver, a skillset or an executor."""

    name: str = Field(min_length=1, max_length=40, pattern=DNS_LABEL)
    """Component name, unique within the system; names its pod and its plugin folder."""
    image: str = Field(min_length=1, max_length=512)
    """Container image."""
    image_pull_policy: Literal["Always", "IfNotPresent", "Never"] | None = None
    """Image pull policy; the cluster default when omitted."""
    command: list[Argument] = Field(default_factory=list, max_length=64)
    """Entrypoint override; the image's entrypoint when empty (executors: `python -m coral.executor`)."""
    args: list[Argument] = Field(default_factory=list, max_length=256)
    """Arguments to the entrypoint."""
    env: list[EnvVar] = Field(default_factory=list, max_length=128)
    """Extra environment variables; the ROS and Coral variables are set by the operator."""
    resources: Resources | None = None
    """Compute resources of the container."""
    devices: list[DeviceMount] = Field(default_factory=list, max_length=32)
    """Robot device files passed into the container."""
    host_paths: list[HostPathMount] = Field(default_factory=list, max_length=32)
    """Robot folders or files mounted into the container."""
    privileged: bool = False
    """Run the container privileged (root on the robot). Allowed only on drivers, and only where the
    operator's policy allows it."""
    run_as_root: bool = False
    """Run as root; components run as non-root by default."""
    transient: bool = False
    """The component may exit 0 and then counts as done (for example a one-shot calibration)."""
    readiness: Readiness | None = None
    """When the component counts as ready; running is enough when omitted (skillsets: plugin marker)."""


GROOT2_DEFAULT_PORT = 1667
"""Groot2's own default; BT.CPP's examples publish there too."""


class Groot2Spec(CamelModel):
    """Publish the executor's live tree over BehaviorTree.CPP's Groot2 protocol, so Groot2 or
    `coral tree watch` can follow it through `coral groot2 SYSTEM ROBOT` (docs/groot2.md)."""

    port: int = Field(default=GROOT2_DEFAULT_PORT, ge=1024, le=65534)
    """Request port; reached breakpoints are published on the next one. Bound on 127.0.0.1 inside
    the pod, which with `ros.network: Host` is the robot's own loopback: executors of every system on
    one robot need ports of their own. 1024 and up, as components run as non-root."""
    allow_hooks: bool = False
    """Let clients set breakpoints and force node results, which change how the tree runs (a forced
    SUCCESS on a safety check). Only in namespaces the operator's policy opens
    (`policy.groot2HooksNamespaces`); watching needs no permission."""
    wait_for_client_seconds: int = Field(default=0, ge=0, le=3600)
    """Hold the mission's first tick until a client sets a hook (or has watched for 3 s), at most
    this long, so a breakpoint can be set before the mission starts; 0 starts at once."""

    def executor_args(self) -> list[str]:
        """The executor's command-line flags for these settings."""
        return [
            "--groot2-port",
            str(self.port),
            *(["--groot2-allow-hooks"] if self.allow_hooks else []),
            *(["--groot2-wait", str(self.wait_for_client_seconds)] if self.wait_for_client_seconds else []),
        ]


class ExecutorMetricsSpec(CamelModel):
    """Serve the executor's Prometheus metrics: tick rate and duration, tree status, behavior
    results and durations, plugin libraries (docs/metrics.md)."""

    port: int = Field(ge=1024, le=65535)
    """Port of `/metrics`, the container port `metrics`. Served on every address of the pod, which
    with `ros.network: Host` are the robot's own: pick a port free on the robot, and one per
    executor. 1024 and up, as components run as non-root."""

    def executor_args(self) -> list[str]:
        """The executor's command-line flags for these settings."""
        return ["--metrics-port", str(self.port)]


class ExecutorComponent(Component):
    """An executor: a component that runs the system's tree."""

    groot2: Groot2Spec | None = None
    """Serve the live tree over Groot2's protocol; off when omitted."""
    metrics: ExecutorMetricsSpec | None = None
    """Serve Prometheus metrics on a port of the pod; off when omitted."""
