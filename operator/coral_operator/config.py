"""The operator's own configuration, read from its environment (set by the Helm chart or the CLI).

Namespace lists are comma separated, `*` meaning every namespace; unset means none. Path lists are
comma separated; unset means the restrictive default, empty means none.

| variable | meaning | unset |
| --- | --- | --- |
| CORAL_POLICY_PRIVILEGED_NAMESPACES | namespaces whose drivers may be privileged | none |
| CORAL_POLICY_ROOT_NAMESPACES | namespaces whose components may run as root | none |
| CORAL_POLICY_HOST_NETWORK_NAMESPACES | namespaces whose systems may use the host network and IPC | none |
| CORAL_POLICY_HOST_PATH_PREFIXES | robot folders host-path mounts may use | /var/lib/coral |
| CORAL_POLICY_DEVICES | device paths (globs) devices may use | /dev/ttyUSB*, /dev/ttyACM*, /dev/video* |
| CORAL_POLICY_PLUGIN_ROOTS | values `plugins.hostPathRoot` may take | /var/lib/coral/plugins |

Read by `handlers` at import time and by `main`.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass

from coral_operator.planning.policy import Policy, normalise


def _parts(value: str) -> list[str]:
    return [part.strip() for part in value.split(",") if part.strip()]


def _namespaces(value: str | None) -> frozenset[str]:
    return frozenset(_parts(value or ""))


def _paths(value: str | None, default: tuple[str, ...]) -> tuple[str, ...]:
    if value is None:
        return default
    return tuple(sorted({normalise(part) for part in _parts(value)}))


@dataclass(frozen=True)
class OperatorConfig:
    """Settings of one operator process."""

    policy: Policy


def from_environment(environ: Mapping[str, str] | None = None) -> OperatorConfig:
    """The configuration from environment variables (see the module docstring)."""
    env = os.environ if environ is None else environ
    defaults = Policy()
    return OperatorConfig(
        policy=Policy(
            privileged_namespaces=_namespaces(env.get("CORAL_POLICY_PRIVILEGED_NAMESPACES")),
            root_namespaces=_namespaces(env.get("CORAL_POLICY_ROOT_NAMESPACES")),
            host_network_namespaces=_namespaces(env.get("CORAL_POLICY_HOST_NETWORK_NAMESPACES")),
            host_path_prefixes=_paths(
                env.get("CORAL_POLICY_HOST_PATH_PREFIXES"), defaults.host_path_prefixes
            ),
            device_patterns=_paths(env.get("CORAL_POLICY_DEVICES"), defaults.device_patterns),
            plugin_roots=_paths(env.get("CORAL_POLICY_PLUGIN_ROOTS"), defaults.plugin_roots),
        ),
    )
