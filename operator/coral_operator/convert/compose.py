"""The Kubernetes side of a Coral compose service: image, entrypoint, devices, mounts, health check.

Coral's own semantics of the file (roles from profiles, `x-coral` options, environment
interpolation, tree and parameters paths) come from the local runtime's parser
(`coral_core.compose`), so `coral run` and `coral convert` read a folder the same way; this module
adds what only matters on a cluster. Entries Kubernetes cannot express are warnings; malformed ones
are errors naming the file and the service. Called by `convert.converting`.
"""

from __future__ import annotations

import shlex
from typing import Any


class ConvertError(ValueError):
    """A folder Coral cannot turn into a CoralSystem; the message names file and field."""


_KNOWN = {
    "image", "profiles", "entrypoint", "command", "environment", "privileged", "devices", "volumes",
    "network_mode", "ipc", "healthcheck", "deploy", "x-coral", "container_name", "depends_on", "restart",
    "stdin_open", "tty", "init", "labels", "hostname",
}  # fmt: skip


def component_name(service: str) -> str:
    """Compose service names allow `_`; component names are DNS labels."""
    return service.lower().replace("_", "-")


def _words(value: Any, where: str) -> list[str]:
    if value is None:
        return []
    if isinstance(value, str):
        return shlex.split(value)
    if isinstance(value, list):
        return [str(v) for v in value]
    raise ConvertError(f"{where}: expected a string or a list")


def _entries(service: dict[str, Any], key: str, where: str) -> list[str | dict[str, Any]]:
    """The list under `key`, each entry a string (short syntax) or a mapping (long syntax)."""
    entries = service.get(key) or []
    if not isinstance(entries, list) or not all(isinstance(e, str | dict) for e in entries):
        raise ConvertError(f"{where}.{key}: expected a list of strings or mappings")
    return entries


def _readiness(check: Any, where: str) -> dict[str, Any] | None:
    if not isinstance(check, dict) or check.get("disable"):
        return None
    test = check.get("test")
    if isinstance(test, str):
        return {"exec": ["sh", "-c", test]}
    if isinstance(test, list) and test and test[0] == "CMD":
        return {"exec": [str(t) for t in test[1:]]}
    if isinstance(test, list) and test and test[0] == "CMD-SHELL":
        return {"exec": ["sh", "-c", " ".join(str(t) for t in test[1:])]}
    raise ConvertError(f"{where}.test: expected a string, [CMD, ...] or [CMD-SHELL, ...]")


def _memory(value: Any) -> str:
    text = str(value).strip()
    for suffix, unit in (("g", "Gi"), ("m", "Mi"), ("k", "Ki")):
        if text.lower().endswith(suffix) or text.lower().endswith(suffix + "b"):
            return text.rstrip("bB")[:-1] + unit
    return text


def kubernetes_fields(service: dict[str, Any], where: str, warnings: list[str]) -> dict[str, Any]:
    """Component fields from one interpolated compose service (`coral_core.compose.Service.fields`):
    everything but name, env and transient."""
    if not service.get("image"):
        raise ConvertError(
            f"{where}.image: required on Kubernetes (the cluster runs images, it does not build)"
        )
    fields: dict[str, Any] = {"image": str(service["image"])}
    if service.get("entrypoint") is not None:
        fields["command"] = _words(service["entrypoint"], f"{where}.entrypoint")
    if service.get("command") is not None:
        fields["args"] = _words(service["command"], f"{where}.command")
    if service.get("privileged"):
        fields["privileged"] = True
    devices = []
    for entry in _entries(service, "devices", where):
        host, _, rest = str(entry).partition(":")
        devices.append({"hostPath": host, **({"containerPath": rest.split(":")[0]} if rest else {})})
    if devices:
        fields["devices"] = devices
    host_paths = []
    for entry in _entries(service, "volumes", where):
        text = entry if isinstance(entry, str) else f"{entry.get('source')}:{entry.get('target')}"
        parts = str(text).split(":")
        if len(parts) >= 2 and parts[0].startswith("/"):
            read_only = len(parts) > 2 and "ro" in parts[2].split(",")
            host_paths.append({"hostPath": parts[0], "mountPath": parts[1], "readOnly": read_only})
        else:
            warnings.append(
                f"{where}.volumes: {text} is not a host bind mount (the operator provides plugins)"
            )
    if host_paths:
        fields["hostPaths"] = host_paths
    readiness = _readiness(service.get("healthcheck"), f"{where}.healthcheck")
    if readiness:
        fields["readiness"] = readiness
    limits = ((service.get("deploy") or {}).get("resources") or {}).get("limits") or {}
    mapped = {}
    if "cpus" in limits:
        mapped["cpu"] = str(limits["cpus"])
    if "memory" in limits:
        mapped["memory"] = _memory(limits["memory"])
    if mapped:
        fields["resources"] = {"limits": mapped}
    if service.get("network_mode") not in (None, "host"):
        warnings.append(f"{where}.network_mode: {service['network_mode']} ignored; see spec.ros.network")
    for key in sorted(set(service) - _KNOWN):
        warnings.append(f"{where}.{key}: not supported on Kubernetes, ignored")
    return fields
