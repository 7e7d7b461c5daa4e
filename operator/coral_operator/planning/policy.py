"""The operator's own privilege policy (DESIGN section 9): who may ask for what on robots.

A CoralSystem asking for more than the policy allows is refused as a whole (Stalled, nothing
deployed). Configured from the operator's settings (`coral_operator.settings`). Pure.
"""

from __future__ import annotations

from dataclasses import dataclass

from coral_operator.api.system import CoralSystemSpec


@dataclass(frozen=True)
class Policy:
    """What CoralSystems may ask for. `None` means no restriction on that axis."""

    privileged_namespaces: frozenset[str] | None = None
    """Namespaces whose drivers may be privileged."""
    host_path_prefixes: tuple[str, ...] | None = None
    """Robot paths that device and host-path mounts may use."""
    host_network_namespaces: frozenset[str] | None = None
    """Namespaces whose systems may use the host network."""


def _under(path: str, prefixes: tuple[str, ...]) -> bool:
    normal = path.rstrip("/") + "/"
    return any(normal.startswith(prefix.rstrip("/") + "/") for prefix in prefixes)


def evaluate_policy(namespace: str, spec: CoralSystemSpec, policy: Policy) -> list[str]:
    """Every way the spec exceeds the policy, one sentence naming the field each; empty if allowed."""
    problems: list[str] = []
    if policy.host_network_namespaces is not None and spec.ros.network == "Host":
        if namespace not in policy.host_network_namespaces:
            problems.append(f"spec.ros.network: host network is not allowed in namespace {namespace}")
    groups = (("drivers", spec.drivers), ("skillsets", spec.skillsets), ("executors", spec.executors))
    for group, components in groups:
        for index, component in enumerate(components):
            where = f"spec.{group}[{index}] ({component.name})"
            if component.privileged and policy.privileged_namespaces is not None:
                if namespace not in policy.privileged_namespaces:
                    problems.append(f"{where}: privileged is not allowed in namespace {namespace}")
            if policy.host_path_prefixes is None:
                continue
            paths = [d.host_path for d in component.devices] + [h.host_path for h in component.host_paths]
            for path in paths:
                if not _under(path, policy.host_path_prefixes):
                    allowed = ", ".join(policy.host_path_prefixes) or "none"
                    problems.append(f"{where}: host path {path} is outside the allowed prefixes ({allowed})")
    return problems
