"""The operator's own configuration, read from its environment (set by the Helm chart or the CLI).

| variable | meaning |
| --- | --- |
| CORAL_POLICY_PRIVILEGED_NAMESPACES | comma list of namespaces allowed privileged drivers; unset: all |
| CORAL_POLICY_HOST_PATH_PREFIXES | robot path prefixes allowed for devices and host paths; unset: all |
| CORAL_POLICY_HOST_NETWORK_NAMESPACES | comma list of namespaces allowed the host network; unset: all |

Read by `handlers` at import time and by `main`.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass

from coral_operator.planning.policy import Policy


def _names(value: str | None) -> frozenset[str] | None:
    if value is None:
        return None
    return frozenset(part.strip() for part in value.split(",") if part.strip())


@dataclass(frozen=True)
class OperatorConfig:
    """Settings of one operator process."""

    policy: Policy


def from_environment(environ: Mapping[str, str] | None = None) -> OperatorConfig:
    """The configuration from environment variables (see the module docstring)."""
    env = os.environ if environ is None else environ
    prefixes = _names(env.get("CORAL_POLICY_HOST_PATH_PREFIXES"))
    return OperatorConfig(
        policy=Policy(
            privileged_namespaces=_names(env.get("CORAL_POLICY_PRIVILEGED_NAMESPACES")),
            host_path_prefixes=tuple(sorted(prefixes)) if prefixes is not None else None,
            host_network_namespaces=_names(env.get("CORAL_POLICY_HOST_NETWORK_NAMESPACES")),
        ),
    )
