"""From a pod the API server gave the robot to the static pod that runs it again offline. Pure.

A static pod may not refer to API objects the kubelet cannot read offline: ConfigMap volumes become
host paths to the files the cache keeps, the ServiceAccount token is dropped (offline there is no
API server to talk to), and the executor writes its status records to a file on the robot instead.
The operator's labels are dropped so a mirror pod is never taken for one of its pods, and a native
sidecar holds the component's lock for as long as the copy runs.
"""

from __future__ import annotations

import copy
import posixpath
from dataclasses import dataclass
from typing import Any

from coral_core import names, offline

EXECUTOR_MODULE = ["python", "-m", "coral.executor"]
DROPPED_LABELS = (names.LABEL_MANAGED_BY, names.LABEL_INSTANCE)
DROPPED_SPEC = ("nodeName", "serviceAccountName", "serviceAccount", "schedulerName", "priority")
RUN_VOLUME = "offline-run"
HOLDER_SCRIPT = "trap 'exit 0' TERM; flock \"$0\" sleep infinity & wait"
"""Holds the lock file given as `$0` until SIGTERM."""


@dataclass(frozen=True)
class StaticCopy:
    """One pod's offline copy and the files its volumes need."""

    pod: dict[str, Any]
    files: dict[str, bytes]
    """Relative path under the cache's `files/` -> content."""


def part_of(pod: dict[str, Any]) -> str:
    """The pod's lock name part: its component, or `robot` for a `PodPerRobot` pod."""
    return pod["metadata"].get("labels", {}).get(names.LABEL_COMPONENT, "robot")


def _config_files(volume: dict[str, Any], config_maps: dict[str, dict[str, str]]) -> dict[str, bytes] | None:
    """The files a ConfigMap (or ConfigMap-only projected) volume shows; None when it shows anything
    else (a token), so the volume is dropped."""
    if "configMap" in volume:
        sources = [{"configMap": volume["configMap"]}]
    elif "projected" in volume:
        sources = volume["projected"].get("sources") or []
    else:
        return {}
    files: dict[str, bytes] = {}
    for source in sources:
        if set(source) != {"configMap"}:
            return None
        ref = source["configMap"]
        data = config_maps[ref["name"]]
        items = ref.get("items") or [{"key": key, "path": key} for key in sorted(data)]
        for item in items:
            files[item["path"]] = data[item["key"]].encode()
    return files


def _executor_args(command: list[str]) -> list[str]:
    """The executor's own command without its API status sink, writing status to the run folder."""
    kept: list[str] = []
    skip = False
    for word in command:
        if skip:
            skip = False
            continue
        if word == "--sink":
            skip = True
            continue
        kept.append(word)
    return [*kept, "--status-jsonl", posixpath.join(offline.RUN_MOUNT, offline.STATUS_FILE)]


def _holder(lock: str, image: str) -> dict[str, Any]:
    path = posixpath.join(offline.LOCK_MOUNT, lock)
    return {
        "name": offline.HOLDER_CONTAINER,
        "image": image,
        "imagePullPolicy": "Never",
        # A native sidecar: started first, stopped last, so the lock is free only once the
        # component's containers are gone.
        "restartPolicy": "Always",
        # The shell is the container's first process, which the kernel spares signals it does not
        # catch: a bare `flock` would sit out the kubelet's grace period (30 s) at every hand-over.
        # On SIGTERM the shell exits, and with it every process of the container, lock and all.
        "command": ["sh", "-c", HOLDER_SCRIPT, path],
        # Started once the lock is taken (another process cannot take it then).
        "startupProbe": {
            "exec": {"command": ["sh", "-c", f"! flock -n {path} true"]},
            "periodSeconds": 1,
            "failureThreshold": 60,
        },
        "volumeMounts": [{"name": offline.LOCKS_VOLUME, "mountPath": offline.LOCK_MOUNT}],
        "securityContext": offline.lock_step_security(),
    }


def static_copy(
    pod: dict[str, Any], *, config_maps: dict[str, dict[str, str]], files_dir: str, run_dir: str
) -> StaticCopy:
    """The static pod running `pod` offline (`pod` as the API server serves it, camelCase).

    `files_dir` is the robot folder holding the cache's files, `run_dir` the one the offline
    executor writes its status to.

    Raises:
        ValueError: the pod has no offline gate (its system does not run offline), or a volume
            names a ConfigMap missing from `config_maps`.
    """
    metadata = pod["metadata"]
    spec = copy.deepcopy(pod["spec"])
    namespace = metadata["namespace"]
    labels = dict(metadata.get("labels") or {})
    system = labels.get(names.LABEL_SYSTEM, "")
    part = part_of(pod)
    inits = spec.get("initContainers") or []
    gate = next((c for c in inits if c["name"] == offline.GATE_CONTAINER), None)
    if gate is None:
        raise ValueError(f"pod {metadata['name']} has no {offline.GATE_CONTAINER} step")
    files: dict[str, bytes] = {}
    volumes: list[dict[str, Any]] = []
    dropped: set[str] = set()
    for volume in spec.get("volumes") or []:
        shown = _config_files(volume, config_maps)
        if shown is None:
            dropped.add(volume["name"])
            continue
        if shown:
            folder = volume["name"]
            files |= {posixpath.join(folder, path): data for path, data in shown.items()}
            volume = {
                "name": volume["name"],
                "hostPath": {"path": posixpath.join(files_dir, folder), "type": "Directory"},
            }
        volumes.append(volume)
    volumes.append({"name": RUN_VOLUME, "hostPath": {"path": run_dir, "type": "DirectoryOrCreate"}})
    spec["volumes"] = volumes
    for key in DROPPED_SPEC:
        spec.pop(key, None)
    spec["automountServiceAccountToken"] = False

    def adapt(container: dict[str, Any]) -> dict[str, Any]:
        container = dict(container)
        container["volumeMounts"] = [
            m for m in container.get("volumeMounts") or [] if m["name"] not in dropped
        ]
        # Offline nothing can be pulled; and the copy must run the image the robot ran.
        container["imagePullPolicy"] = "Never"
        command = list(container.get("command") or [])
        if command[:3] == EXECUTOR_MODULE:
            container["command"] = _executor_args(command)
            container["volumeMounts"].append({"name": RUN_VOLUME, "mountPath": offline.RUN_MOUNT})
        return container

    lock = offline.lock_name(namespace, system, part)
    spec["initContainers"] = [_holder(lock, gate["image"])] + [
        adapt(c) for c in inits if c["name"] != offline.GATE_CONTAINER
    ]
    spec["containers"] = [adapt(c) for c in spec["containers"]]
    static_labels = {k: v for k, v in labels.items() if k not in DROPPED_LABELS}
    static_labels[offline.LABEL_OFFLINE_COPY] = part
    static_pod = {
        "apiVersion": "v1",
        "kind": "Pod",
        "metadata": {
            "name": f"{offline.STATIC_POD_PREFIX}{system}-{part}"[:200],
            "namespace": namespace,
            "labels": static_labels,
        },
        "spec": spec,
    }
    return StaticCopy(static_pod, files)
