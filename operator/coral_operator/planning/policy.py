"""The operator's own privilege policy: who may ask for what on robots (docs/architecture.md).

Whoever may create a CoralSystem in a namespace may start processes on robots. The policy decides
which of the spec's fields that reach a pod may grant more than an unprivileged container:
`privileged`, `runAsRoot`, devices, host paths, `plugins.hostPathRoot` and the host network (with
host IPC). Pods the operator builds never ask for hostPID or added capabilities, and non-root
containers drop every capability. The shipped default (`Policy()`) is restrictive; administrators
open it per namespace (`coral_operator.config`). A CoralSystem asking for more is refused as a
whole (Stalled, nothing deployed). Paths are normalised before they are compared, so `..` cannot
climb out of an allowed folder. Pure.
"""

from __future__ import annotations

import posixpath
from dataclasses import dataclass
from pathlib import PurePosixPath

from coral_operator.api.components import Component
from coral_operator.api.instance import CoralInstanceSpec
from coral_operator.api.system import CoralSystemSpec

ANY_NAMESPACE = "*"
DEFAULT_PLUGIN_ROOT = "/var/lib/coral/plugins"
DEFAULT_HOST_PATH_PREFIXES = ("/var/lib/coral",)
DEFAULT_DEVICE_PATTERNS = ("/dev/ttyUSB*", "/dev/ttyACM*", "/dev/video*")


@dataclass(frozen=True)
class Policy:
    """What CoralSystems may ask for. Namespace sets may hold `*` for every namespace."""

    privileged_namespaces: frozenset[str] = frozenset()
    """Namespaces whose drivers may be privileged (root on the robot, every device)."""
    root_namespaces: frozenset[str] = frozenset()
    """Namespaces whose components may run as root (`runAsRoot`)."""
    host_network_namespaces: frozenset[str] = frozenset()
    """Namespaces whose systems may use the host network and host IPC (`ros.network: Host`, which
    ROS 2 DDS discovery between robots and shared-memory transport need)."""
    host_path_prefixes: tuple[str, ...] = DEFAULT_HOST_PATH_PREFIXES
    """Robot folders under which `hostPaths` may mount, except the plugin roots."""
    device_patterns: tuple[str, ...] = DEFAULT_DEVICE_PATTERNS
    """Robot device paths `devices` may pass in, as glob patterns (`*` stays within one name)."""
    plugin_roots: tuple[str, ...] = (DEFAULT_PLUGIN_ROOT,)
    """Values `plugins.hostPathRoot` may take: the operator creates `<root>/<namespace>/<system>`
    read-write on every robot, so any other root could reach another namespace's plugins."""


def allows(namespaces: frozenset[str], namespace: str) -> bool:
    return ANY_NAMESPACE in namespaces or namespace in namespaces


def normalise(path: str) -> str:
    """The absolute path with `.`, `..` and repeated slashes resolved, as the robot's kernel would
    (symbolic links on the robot aside)."""
    normal = posixpath.normpath("/" + path.lstrip("/"))
    # POSIX keeps a leading `//`; the kernel does not tell it from `/`.
    return "/" + normal.lstrip("/")


def is_under(path: str, folder: str) -> bool:
    """`path` is `folder` or inside it; both normalised."""
    path, folder = normalise(path), normalise(folder)
    return folder == "/" or path == folder or path.startswith(folder + "/")


def _overlaps(path: str, folder: str) -> bool:
    return is_under(path, folder) or is_under(folder, path)


def _device_allowed(path: str, patterns: tuple[str, ...]) -> bool:
    normal = PurePosixPath(normalise(path))
    # An absolute pattern of as many names as the path: `match` then compares the whole path,
    # and its `*` never crosses a `/`.
    return any(
        len(normal.parts) == len(PurePosixPath(pattern).parts) and normal.match(pattern)
        for pattern in patterns
    )


def _component_problems(where: str, component: Component, namespace: str, policy: Policy) -> list[str]:
    problems: list[str] = []
    if component.privileged and not allows(policy.privileged_namespaces, namespace):
        problems.append(f"{where}: privileged is not allowed in namespace {namespace}")
    if component.run_as_root and not allows(policy.root_namespaces, namespace):
        problems.append(f"{where}: runAsRoot is not allowed in namespace {namespace}")
    for index, device in enumerate(component.devices):
        if not _device_allowed(device.host_path, policy.device_patterns):
            allowed = ", ".join(policy.device_patterns) or "none"
            problems.append(
                f"{where}: devices[{index}].hostPath {normalise(device.host_path)} is not an allowed "
                f"device ({allowed})"
            )
    for index, mount in enumerate(component.host_paths):
        path = normalise(mount.host_path)
        field = f"{where}: hostPaths[{index}].hostPath"
        if not any(is_under(path, prefix) for prefix in policy.host_path_prefixes):
            allowed = ", ".join(policy.host_path_prefixes) or "none"
            problems.append(f"{field}: host path {path} is outside the allowed prefixes ({allowed})")
        elif any(_overlaps(path, root) for root in policy.plugin_roots):
            problems.append(
                f"{field}: host path {path} overlaps the plugin root, which holds other systems' plugins"
            )
    return problems


def evaluate_policy(namespace: str, spec: CoralSystemSpec | CoralInstanceSpec, policy: Policy) -> list[str]:
    """Every way the spec exceeds the policy, one sentence naming the field each; empty if allowed.

    Checked on a CoralSystem before anything is deployed, and again on each CoralInstance before
    its pods are built (`planning.provenance`): the fields that reach a pod are the same in both.
    """
    problems: list[str] = []
    if spec.ros.network == "Host" and not allows(policy.host_network_namespaces, namespace):
        problems.append(
            f"spec.ros.network: the host network (Host) is not allowed in namespace {namespace}; use Pod"
        )
    root = normalise(spec.plugins.host_path_root)
    if root not in {normalise(allowed) for allowed in policy.plugin_roots}:
        problems.append(
            f"spec.plugins.hostPathRoot: {root} is not an allowed plugin root "
            f"({', '.join(policy.plugin_roots)})"
        )
    groups = (("drivers", spec.drivers), ("skillsets", spec.skillsets), ("executors", spec.executors))
    for group, components in groups:
        for index, component in enumerate(components):
            where = f"spec.{group}[{index}] ({component.name})"
            problems += _component_problems(where, component, namespace, policy)
    return problems
