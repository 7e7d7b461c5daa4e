"""Materialises a pod's volumes as local folders of its robot, and maps its mounts onto them.

Called by `runner.pods` before a pod's first container starts. Layout under the runner's root:

    <root>/<robot>/host/<path>                      hostPath volumes (shared by the robot's pods)
    <root>/<robot>/pods/<namespace>_<pod>/volumes/  configMap, secret, downwardAPI, projected, emptyDir

ConfigMap, Secret and token contents are written once, when the pod starts (a kubelet would
refresh them; the runner does not). Unsupported volume types raise `ContainerConfigError`.
"""

from __future__ import annotations

import base64
import shutil
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from coral_testbed.runner import podspec

# (namespace, service account, pod name, pod uid) -> a bound token for that account.
TokenSource = Callable[[str, str, str, str], str]

SERVICE_ACCOUNT_DIR = "/var/run/secrets/kubernetes.io/serviceaccount"


def host_path(robot_root: Path, path: str) -> Path:
    """Where a hostPath of this robot lives locally."""
    relative = Path(path).relative_to("/") if path.startswith("/") else Path(path)
    if ".." in relative.parts:
        raise podspec.ContainerConfigError(f"hostPath {path!r} must not contain '..'")
    return robot_root / "host" / relative


def pod_dir(robot_root: Path, pod: Mapping[str, Any]) -> Path:
    meta = pod["metadata"]
    return robot_root / "pods" / f"{meta.get('namespace', 'default')}_{meta['name']}"


def _write_items(
    folder: Path, data: Mapping[str, str], items: list[dict[str, Any]] | None, where: str
) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    chosen = [(i["key"], i.get("path", i["key"])) for i in items] if items else [(k, k) for k in data]
    for key, relative in chosen:
        if key not in data:
            raise podspec.ContainerConfigError(f"{where}: no key {key!r}")
        target = folder / relative
        if ".." in Path(relative).parts:
            raise podspec.ContainerConfigError(f"{where}: item path {relative!r} must not contain '..'")
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_text(data[key])


def _object_source(
    source: Mapping[str, Any], kind: str, namespace: str, lookup: podspec.Lookup, folder: Path, where: str
) -> None:
    name = source.get("name") or source.get("secretName") or ""
    data = lookup(kind, namespace, name)
    if data is None:
        if source.get("optional"):
            folder.mkdir(parents=True, exist_ok=True)
            return
        raise podspec.ContainerConfigError(f"{where}: {kind} {namespace}/{name} not found")
    _write_items(folder, data, source.get("items"), f"{where}: {kind} {namespace}/{name}")


def _downward(
    source: Mapping[str, Any], pod: Mapping[str, Any], host_ip: str, folder: Path, where: str
) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    for item in source.get("items") or []:
        if "fieldRef" not in item:
            raise podspec.ContainerConfigError(f"{where}: only fieldRef items are supported")
        target = folder / item["path"]
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_text(podspec.field_value(pod, item["fieldRef"]["fieldPath"], host_ip))


def materialise(
    pod: Mapping[str, Any],
    robot_root: Path,
    lookup: podspec.Lookup,
    tokens: TokenSource,
    host_ip: str,
) -> dict[str, Path]:
    """Creates every volume of `pod`; returns volume name -> local folder."""
    meta, spec = pod["metadata"], pod.get("spec") or {}
    namespace = meta.get("namespace", "default")
    base = pod_dir(robot_root, pod) / "volumes"
    made: dict[str, Path] = {}
    for volume in spec.get("volumes") or []:
        name = volume["name"]
        where = f"volumes[{name}]"
        folder = base / name
        if "hostPath" in volume:
            local = host_path(robot_root, volume["hostPath"]["path"])
            kind = volume["hostPath"].get("type") or ""
            if kind in ("Directory", "File", "Socket", "CharDevice", "BlockDevice") and not local.exists():
                raise podspec.ContainerConfigError(f"{where}: hostPath {local} does not exist (type {kind})")
            if kind == "FileOrCreate":
                local.parent.mkdir(parents=True, exist_ok=True)
                local.touch(exist_ok=True)
            elif not local.exists():
                local.mkdir(parents=True, exist_ok=True)
            made[name] = local
            continue
        if folder.exists():
            shutil.rmtree(folder)
        if "emptyDir" in volume:
            folder.mkdir(parents=True)
        elif "configMap" in volume:
            _object_source(volume["configMap"], "ConfigMap", namespace, lookup, folder, where)
        elif "secret" in volume:
            _object_source(volume["secret"], "Secret", namespace, lookup, folder, where)
        elif "downwardAPI" in volume:
            _downward(volume["downwardAPI"], pod, host_ip, folder, where)
        elif "projected" in volume:
            folder.mkdir(parents=True)
            for index, source in enumerate(volume["projected"].get("sources") or []):
                at = f"{where}.sources[{index}]"
                if "configMap" in source:
                    _object_source(source["configMap"], "ConfigMap", namespace, lookup, folder, at)
                elif "secret" in source:
                    _object_source(source["secret"], "Secret", namespace, lookup, folder, at)
                elif "downwardAPI" in source:
                    _downward(source["downwardAPI"], pod, host_ip, folder, at)
                elif "serviceAccountToken" in source:
                    account = spec.get("serviceAccountName") or "default"
                    token = tokens(namespace, account, meta["name"], meta.get("uid", ""))
                    (folder / source["serviceAccountToken"].get("path", "token")).write_text(token)
                else:
                    raise podspec.ContainerConfigError(f"{at}: source {sorted(source)} is not supported")
        else:
            kinds = sorted(k for k in volume if k != "name")
            raise podspec.ContainerConfigError(f"{where}: volume type {kinds} is not supported")
        made[name] = folder
    return made


def mount_map(container: Mapping[str, Any], volumes: Mapping[str, Path]) -> podspec.PathMap:
    """The container's mount paths -> local paths (subPath resolved), for path rewriting."""
    mounts: dict[str, Path] = {}
    for mount in container.get("volumeMounts") or []:
        name = mount["name"]
        if name not in volumes:
            raise podspec.ContainerConfigError(
                f"containers[{container.get('name')}].volumeMounts[{name}]: no such volume"
            )
        local = volumes[name]
        sub = mount.get("subPath")
        if sub:
            local = local / sub
        mounts[mount["mountPath"]] = local
    return podspec.PathMap.of(mounts)


def decode_secret(data: Mapping[str, str] | None) -> dict[str, str] | None:
    """Secret `data` is base64; the runner hands processes the decoded text."""
    if data is None:
        return None
    return {k: base64.b64decode(v).decode("utf-8", errors="replace") for k, v in data.items()}
