"""Pure translation of a pod's container spec into a local process: environment, paths and argv.

Called by `runner.pods` for every container it starts and every exec probe it runs. Nothing here
talks to the API: ConfigMaps and Secrets come in through the `lookup` callable, so the rules (the
order of `envFrom` and `env`, `$(VAR)` expansion, downward-API fields) are testable on their own.

Container paths are not real on this machine, so every volume mount becomes a prefix rewrite:
a string in the command, arguments, environment values or probe command that starts with a
mount path (at a word boundary) is pointed at the volume's local folder instead.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

# (kind, namespace, name) -> the object's data (ConfigMap data, decoded Secret data) or None if absent.
Lookup = Callable[[str, str, str], Mapping[str, str] | None]

_VAR_REF = re.compile(r"\$\$|\$\(([A-Za-z_][A-Za-z0-9_.-]*)\)")


class ContainerConfigError(ValueError):
    """The container cannot start as specified (missing ConfigMap key, unsupported field, ...).

    Reported on the pod as waiting reason CreateContainerConfigError, like the kubelet does.
    """


def expand(text: str, env: Mapping[str, str]) -> str:
    """Kubernetes `$(VAR)` expansion: known variables are replaced, unknown ones kept, `$$` is `$`."""

    def replace(match: re.Match[str]) -> str:
        if match.group(0) == "$$":
            return "$"
        name = match.group(1)
        return env[name] if name in env else match.group(0)

    return _VAR_REF.sub(replace, text)


_FIELD_LABEL = re.compile(r"^metadata\.(labels|annotations)\['([^']+)'\]$")


def field_value(pod: Mapping[str, Any], path: str, host_ip: str) -> str:
    """The value of a downward-API `fieldRef.fieldPath` for this pod."""
    meta = pod.get("metadata") or {}
    spec = pod.get("spec") or {}
    simple = {
        "metadata.name": meta.get("name", ""),
        "metadata.namespace": meta.get("namespace", ""),
        "metadata.uid": meta.get("uid", ""),
        "spec.nodeName": spec.get("nodeName", ""),
        "spec.serviceAccountName": spec.get("serviceAccountName", "default"),
        "status.hostIP": host_ip,
        "status.hostIPs": host_ip,
        "status.podIP": host_ip,
        "status.podIPs": host_ip,
    }
    if path in simple:
        return str(simple[path])
    match = _FIELD_LABEL.match(path)
    if match:
        return str((meta.get(match.group(1)) or {}).get(match.group(2), ""))
    if path in ("metadata.labels", "metadata.annotations"):
        items = meta.get(path.split(".")[1]) or {}
        return "\n".join(f'{k}="{v}"' for k, v in sorted(items.items()))
    raise ContainerConfigError(f"fieldRef.fieldPath {path!r} is not supported by the robot runner")


def _key_ref(ref: Mapping[str, Any], kind: str, namespace: str, lookup: Lookup, where: str) -> str | None:
    data = lookup(kind, namespace, ref.get("name", ""))
    optional = bool(ref.get("optional"))
    if data is None:
        if optional:
            return None
        raise ContainerConfigError(f"{where}: {kind} {namespace}/{ref.get('name')} not found")
    key = ref.get("key", "")
    if key not in data:
        if optional:
            return None
        raise ContainerConfigError(f"{where}: {kind} {namespace}/{ref.get('name')} has no key {key!r}")
    return data[key]


def container_env(
    pod: Mapping[str, Any], container: Mapping[str, Any], lookup: Lookup, host_ip: str
) -> dict[str, str]:
    """The container's variables in Kubernetes order: `envFrom` first, then `env` (which wins)."""
    namespace = (pod.get("metadata") or {}).get("namespace", "default")
    name = container.get("name", "?")
    env: dict[str, str] = {}
    for index, source in enumerate(container.get("envFrom") or []):
        prefix = source.get("prefix", "")
        for kind, key in (("ConfigMap", "configMapRef"), ("Secret", "secretRef")):
            ref = source.get(key)
            if ref is None:
                continue
            data = lookup(kind, namespace, ref.get("name", ""))
            if data is None:
                if ref.get("optional"):
                    continue
                raise ContainerConfigError(
                    f"containers[{name}].envFrom[{index}]: {kind} {namespace}/{ref.get('name')} not found"
                )
            env.update({prefix + k: v for k, v in data.items()})
    for item in container.get("env") or []:
        where = f"containers[{name}].env[{item.get('name')}]"
        source = item.get("valueFrom")
        if source is None:
            env[item["name"]] = expand(str(item.get("value", "")), env)
            continue
        value: str | None
        if "fieldRef" in source:
            value = field_value(pod, source["fieldRef"].get("fieldPath", ""), host_ip)
        elif "configMapKeyRef" in source:
            value = _key_ref(source["configMapKeyRef"], "ConfigMap", namespace, lookup, where)
        elif "secretKeyRef" in source:
            value = _key_ref(source["secretKeyRef"], "Secret", namespace, lookup, where)
        else:
            raise ContainerConfigError(f"{where}: valueFrom {sorted(source)} is not supported")
        if value is not None:
            env[item["name"]] = value
    return env


# A mount path is rewritten where it starts a path: at the start, after a separator or an opening
# quote or bracket (so `python -c "open('/data/x')"` works), and only up to a path boundary.
_BEFORE = r"(?:(?<=^)|(?<=[\s=:,'\"(\[]))"
_AFTER = r"(?=/|$|[\s:;,'\")\]])"


@dataclass(frozen=True)
class PathMap:
    """Container mount paths and the local folders (or files) that stand in for them."""

    mounts: tuple[tuple[str, Path], ...]

    @classmethod
    def of(cls, mounts: Mapping[str, Path]) -> PathMap:
        # Longest first, so /coral/config/x wins over /coral.
        ordered = sorted(mounts.items(), key=lambda item: len(item[0]), reverse=True)
        return cls(tuple((path.rstrip("/") or "/", local) for path, local in ordered))

    def rewrite(self, text: str) -> str:
        """Replaces every mount path that starts a path in `text` (see `_BEFORE` and `_AFTER`)."""
        for container_path, local in self.mounts:
            if container_path == "/":
                continue
            pattern = re.compile(_BEFORE + re.escape(container_path) + _AFTER)
            text = pattern.sub(lambda _m, local=local: str(local), text)
        return text

    def local(self, container_path: str) -> Path | None:
        """The local path of a container path, if some mount covers it."""
        rewritten = self.rewrite(container_path)
        return Path(rewritten) if rewritten != container_path else None


def image_key(image: str) -> str:
    """An image reference without tag or digest: `reg/x:1.0@sha256:..` -> `reg/x`."""
    name = image.split("@", 1)[0]
    slash = name.rfind("/")
    colon = name.rfind(":")
    return name[:colon] if colon > slash else name


def container_argv(
    container: Mapping[str, Any],
    env: Mapping[str, str],
    paths: PathMap,
    entrypoints: Mapping[str, list[str]],
) -> list[str]:
    """`command` + `args` with `$(VAR)` expanded and mount paths rewritten.

    A container without `command` uses its image's entrypoint from `entrypoints` (keyed by image
    name without tag), as the image's ENTRYPOINT would be used by a container runtime.

    Raises:
        ContainerConfigError: no command and no entrypoint known for the image.
    """
    command = list(container.get("command") or [])
    args = list(container.get("args") or [])
    if not command:
        image = str(container.get("image", ""))
        command = list(entrypoints.get(image_key(image)) or entrypoints.get(image) or [])
    if not command:
        raise ContainerConfigError(
            f"containers[{container.get('name')}]: no command, and image {container.get('image')!r} "
            "has no local entrypoint; the robot runner does not run images: give the container a "
            "command or map the image with --image-command IMAGE='python -m module'"
        )
    return [paths.rewrite(expand(str(part), env)) for part in command + args]
