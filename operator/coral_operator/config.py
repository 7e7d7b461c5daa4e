"""The operator's own configuration, read from its environment (set by the Helm chart or the CLI).

Namespace lists are comma separated, `*` meaning every namespace; unset means none. Path lists are
comma separated; unset means the restrictive default, empty means none. Host paths are pairs
`namespace=/folder` (or `*=/folder`), comma separated.

| variable | meaning | unset |
| --- | --- | --- |
| CORAL_POLICY_PRIVILEGED_NAMESPACES | namespaces whose drivers may be privileged | none |
| CORAL_POLICY_ROOT_NAMESPACES | namespaces whose components may run as root | none |
| CORAL_POLICY_HOST_NETWORK_NAMESPACES | namespaces whose systems may use the host network and IPC | none |
| CORAL_POLICY_GROOT2_HOOKS_NAMESPACES | namespaces whose executors may take Groot2 hooks | none |
| CORAL_POLICY_DATA_ROOT | robot folder of the data subtrees, `<root>/<namespace>` | /var/lib/coral/data |
| CORAL_POLICY_HOST_PATHS | further folders a namespace may mount, `namespace=/folder` | none |
| CORAL_POLICY_DEVICES | device paths (globs) devices may use | /dev/ttyUSB*, /dev/ttyACM*, /dev/video* |
| CORAL_POLICY_PLUGIN_ROOTS | values `plugins.hostPathRoot` may take | /var/lib/coral/plugins |
| CORAL_HELPER_IMAGE | image of the step that hands folders to the components' user | the operator's |
| CORAL_PREFLIGHT_REGISTRIES | registries (`host[:port]`, `*`: all) preflight reads images from | none |

Read by `handlers` at import time and by `main`. A setting that cannot be read stops the operator
at start with a sentence naming it, rather than serving with a policy nobody meant.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass

from coral_operator.planning.pods import DEFAULT_HELPER_IMAGE
from coral_operator.planning.policy import ANY_NAMESPACE, Policy, is_under, normalise

_NAMESPACE_CHARS = frozenset("abcdefghijklmnopqrstuvwxyz0123456789-")
# Read by operators before issue 47; any prefix let every namespace reach every other's data.
_RETIRED = {
    "CORAL_POLICY_HOST_PATH_PREFIXES": "use CORAL_POLICY_HOST_PATHS (namespace=/folder) and the "
    "namespaces' own data subtrees under CORAL_POLICY_DATA_ROOT",
}


def _parts(value: str) -> list[str]:
    return [part.strip() for part in value.split(",") if part.strip()]


def _namespaces(value: str | None) -> frozenset[str]:
    return frozenset(_parts(value or ""))


def _paths(value: str | None, default: tuple[str, ...]) -> tuple[str, ...]:
    if value is None:
        return default
    return tuple(sorted({normalise(part) for part in _parts(value)}))


def _host_paths(value: str | None) -> tuple[tuple[str, str], ...]:
    pairs: set[tuple[str, str]] = set()
    for part in _parts(value or ""):
        namespace, _, folder = (piece.strip() for piece in part.partition("="))
        valid_namespace = namespace == ANY_NAMESPACE or (
            namespace and set(namespace) <= _NAMESPACE_CHARS and len(namespace) <= 63
        )
        if not valid_namespace or not folder.startswith("/"):
            raise ValueError(
                f"CORAL_POLICY_HOST_PATHS: {part!r} is not namespace=/folder (a namespace or *, "
                "then an absolute robot folder)"
            )
        pairs.add((namespace, normalise(folder)))
    return tuple(sorted(pairs))


def _check(policy: Policy) -> None:
    for root in policy.plugin_roots:
        if is_under(policy.data_root, root) or is_under(root, policy.data_root):
            raise ValueError(
                f"CORAL_POLICY_DATA_ROOT: {policy.data_root} overlaps the plugin root {root}; a "
                "namespace's data subtree must never hold or be another namespace's plugins"
            )
    if policy.data_root == "/":
        raise ValueError("CORAL_POLICY_DATA_ROOT: / would give each namespace a top-level robot folder")


@dataclass(frozen=True)
class OperatorConfig:
    """Settings of one operator process."""

    policy: Policy
    helper_image: str = DEFAULT_HELPER_IMAGE
    """The image the ownership step of component pods runs as root with CAP_CHOWN alone: one the
    administrator chose, never a tenant's (`planning.pods`)."""
    preflight_registries: frozenset[str] = frozenset()
    """Registries the operator reads component images' declarations from (`reconcile.declarations`)."""


def from_environment(environ: Mapping[str, str] | None = None) -> OperatorConfig:
    """The configuration from environment variables (see the module docstring).

    Raises:
        ValueError: a setting cannot be read, or a retired one is set; the message names it.
    """
    env = os.environ if environ is None else environ
    for name, instead in _RETIRED.items():
        if name in env:
            raise ValueError(f"{name} is no longer read: {instead}")
    defaults = Policy()
    policy = Policy(
        privileged_namespaces=_namespaces(env.get("CORAL_POLICY_PRIVILEGED_NAMESPACES")),
        root_namespaces=_namespaces(env.get("CORAL_POLICY_ROOT_NAMESPACES")),
        host_network_namespaces=_namespaces(env.get("CORAL_POLICY_HOST_NETWORK_NAMESPACES")),
        groot2_hooks_namespaces=_namespaces(env.get("CORAL_POLICY_GROOT2_HOOKS_NAMESPACES")),
        data_root=normalise(env.get("CORAL_POLICY_DATA_ROOT") or defaults.data_root),
        host_paths=_host_paths(env.get("CORAL_POLICY_HOST_PATHS")),
        device_patterns=_paths(env.get("CORAL_POLICY_DEVICES"), defaults.device_patterns),
        plugin_roots=_paths(env.get("CORAL_POLICY_PLUGIN_ROOTS"), defaults.plugin_roots),
    )
    _check(policy)
    return OperatorConfig(
        policy=policy,
        helper_image=env.get("CORAL_HELPER_IMAGE") or DEFAULT_HELPER_IMAGE,
        preflight_registries=frozenset(_parts(env.get("CORAL_PREFLIGHT_REGISTRIES") or "")),
    )
