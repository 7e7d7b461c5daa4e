"""The operator's own privilege policy: who may ask for what on robots (docs/architecture.md).

Whoever may create a CoralSystem in a namespace may start processes on robots. The policy decides
which of the spec's fields that reach a pod may grant more than an unprivileged container:
`privileged`, `runAsRoot`, devices, host paths, `plugins.hostPathRoot`, the host network (with
host IPC) and Groot2 hooks on an executor (breakpoints and forced node results, which change how
the tree runs: a forced SUCCESS on a safety check is as good as root; watching is always allowed).
Pods the operator builds never ask for hostPID or added capabilities, and non-root containers drop
every capability. The shipped default (`Policy()`) is restrictive; administrators
open it per namespace (`coral_operator.config`). A CoralSystem asking for more is refused as a
whole (Stalled, nothing deployed). Paths are normalised before they are compared, so `..` cannot
climb out of an allowed folder. Pure.

Host paths are owned (issue 47): a namespace may mount only folders inside its own data subtree
`<data root>/<namespace>`, or inside a folder an administrator listed for it. `host_path_volume`
says which of those folders a path lies in, so the pod builder mounts that folder as the volume
and the rest of the path as a `subPath`, which the kubelet resolves without following a link out
of the volume: a link a tenant planted inside cannot lead to `/etc` or another namespace.
"""

from __future__ import annotations

import posixpath
from dataclasses import dataclass
from pathlib import PurePosixPath

from coral_operator.api.components import Component, ExecutorComponent
from coral_operator.api.instance import CoralInstanceSpec
from coral_operator.api.system import CoralSystemSpec

ANY_NAMESPACE = "*"
DEFAULT_PLUGIN_ROOT = "/var/lib/coral/plugins"
DEFAULT_DATA_ROOT = "/var/lib/coral/data"
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
    data_root: str = DEFAULT_DATA_ROOT
    """The robot folder holding one data subtree per namespace, `<data_root>/<namespace>`: a
    namespace's `hostPaths` may mount anything inside its own, and nothing of another's."""
    host_paths: tuple[tuple[str, str], ...] = ()
    """(namespace or `*`, robot folder) pairs an administrator opened: the namespace may mount that
    folder or anything inside it, besides its data subtree. A folder listed for two namespaces, or
    for `*`, is shared between them (read-only data such as maps and bags)."""
    device_patterns: tuple[str, ...] = DEFAULT_DEVICE_PATTERNS
    """Robot device paths `devices` may pass in, as glob patterns (`*` stays within one name)."""
    groot2_hooks_namespaces: frozenset[str] = frozenset()
    """Namespaces whose executors may let Groot2 clients set breakpoints and force node results
    (`groot2.allowHooks`)."""
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


def data_subtree(policy: Policy, namespace: str) -> str:
    """The namespace's own data folder on every robot."""
    return posixpath.join(normalise(policy.data_root), namespace)


def allowed_folders(policy: Policy, namespace: str) -> list[str]:
    """The folders the namespace's host paths may lie in: its data subtree first, then the
    administrator's folders for it."""
    listed = {normalise(folder) for ns, folder in policy.host_paths if ns in (namespace, ANY_NAMESPACE)}
    return [data_subtree(policy, namespace), *sorted(listed)]


def host_path_volume(policy: Policy, namespace: str, path: str) -> tuple[str, str] | None:
    """The (volume folder, subPath) a host path of the namespace is mounted as, or None when the
    policy does not let the namespace mount it.

    The volume is the allowed folder the path lies in (the innermost, if listed folders nest), the
    subPath the rest of the path, empty for the folder itself. Nothing but the operator writes
    the volume folder's own parents, so the kubelet, which opens every name of the subPath
    without following links out of the volume, keeps the mount inside the folder.
    """
    normal = normalise(path)
    inside = [folder for folder in allowed_folders(policy, namespace) if is_under(normal, folder)]
    if not inside:
        return None
    folder = max(inside, key=len)
    return folder, posixpath.relpath(normal, folder) if normal != folder else ""


def _device_allowed(path: str, patterns: tuple[str, ...]) -> bool:
    normal = PurePosixPath(normalise(path))
    # An absolute pattern of as many names as the path: `match` then compares the whole path,
    # and its `*` never crosses a `/`.
    return any(
        len(normal.parts) == len(PurePosixPath(pattern).parts) and normal.match(pattern)
        for pattern in patterns
    )


ALLOW_HOOKS_FLAG = "--groot2-allow-hooks"


def _groot2_problems(where: str, component: Component, namespace: str, policy: Policy) -> list[str]:
    if allows(policy.groot2_hooks_namespaces, namespace):
        return []
    problems = []
    if isinstance(component, ExecutorComponent) and component.groot2 and component.groot2.allow_hooks:
        problems.append(f"{where}: groot2.allowHooks is not allowed in namespace {namespace}")
    # The flag written by hand would be the same permission without the field.
    for field, values in (("command", component.command), ("args", component.args)):
        if any(value.strip() == ALLOW_HOOKS_FLAG for value in values):
            problems.append(
                f"{where}: {field} holds {ALLOW_HOOKS_FLAG}, which is not allowed in namespace {namespace}"
            )
    return problems


def _component_problems(where: str, component: Component, namespace: str, policy: Policy) -> list[str]:
    problems = _groot2_problems(where, component, namespace, policy)
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
        if host_path_volume(policy, namespace, path) is None:
            allowed = ", ".join(allowed_folders(policy, namespace))
            problems.append(
                f"{field}: host path {path} is outside the folders namespace {namespace} may mount "
                f"({allowed})"
            )
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
    # What an override adds reaches some robot's pods just as well.
    for override in getattr(spec, "overrides", []):
        for group in ("drivers", "skillsets", "executors"):
            for index, component in enumerate(getattr(override.add, group)):
                where = f"spec.overrides[{override.name}].add.{group}[{index}] ({component.name})"
                problems += _component_problems(where, component, namespace, policy)
    return problems
