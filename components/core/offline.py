"""Offline autonomy: what the operator and the robot's agent agree on (docs/offline.md).

A robot keeps a sealed copy of the last revision it ran (its pods as static pods, and the files of
the ConfigMaps they mount); when it boots without the API server, its agent checks the seal and hands
the copy to the kubelet as static pods. One file lock per component on the robot makes sure an
offline copy and the API server's copy never run at once: the offline copy holds it while it runs,
the API copy's first init step waits for it. Pure: paths, names, the cache's format and seal, and
the two decisions (what to start at boot, when to hand over).
"""

from __future__ import annotations

import hashlib
import hmac
import json
import posixpath
from dataclasses import dataclass
from enum import StrEnum
from typing import Any

from coral_core.names import GROUP

LABEL_OFFLINE = f"{GROUP}/offline"
"""On a pod the operator builds: the system lets the robot run its last revision offline."""
LABEL_OFFLINE_COPY = f"{GROUP}/offline-copy"
"""On a static pod the agent wrote: the component it runs. Never the operator's labels, so a mirror
pod is not taken for one of the operator's pods."""
ANNOTATION_INTERRUPT = f"{GROUP}/offline-interrupt-running-trees"
"""On a pod: "true" when the hand-over may stop an offline tree that is still running."""
ANNOTATION_NODE_REPORT = f"{GROUP}/offline-report"
"""On a robot's Node: the agent's last boot report (JSON), written once the link is back."""

ROOT = "/var/lib/coral/offline"
"""The robot's folder for the cache, its key, the locks and the offline runs' status."""
LOCKS_DIR = posixpath.join(ROOT, "locks")
CACHES_DIR = posixpath.join(ROOT, "systems")
RUNS_DIR = posixpath.join(ROOT, "runs")
KEY_FILE = posixpath.join(ROOT, "key")
REPORT_FILE = posixpath.join(ROOT, "report.json")
STATIC_POD_DIR = "/var/lib/kubelet/coral-static"
"""The kubelet's `staticPodPath` on a robot (KubeletConfiguration)."""
STATIC_POD_PREFIX = "coral-offline-"
"""Only files with this prefix in the static pod folder are the agent's."""

GATE_CONTAINER = "offline-gate"
HOLDER_CONTAINER = "offline-lock"
LOCKS_VOLUME = "offline-locks"
LOCK_MOUNT = "/coral-offline-locks"
"""Where the gate and the holder see `LOCKS_DIR`."""
RUN_MOUNT = "/coral-offline-run"
"""Where an offline executor writes its status records (`RUNS_DIR/<cache>`)."""
STATUS_FILE = "status.jsonl"

MANIFEST_FILE = "manifest.json"
SEAL_FILE = "seal"
FILES_DIR = "files"
FORMAT = 1


def lock_step_security() -> dict[str, Any]:
    """The gate's and the holder's security context: root (the lock folder is root's), no capability."""
    return {
        "runAsUser": 0,
        "runAsNonRoot": False,
        "allowPrivilegeEscalation": False,
        "capabilities": {"drop": ["ALL"]},
    }


def lock_name(namespace: str, system: str, part: str) -> str:
    """The lock file of one pod (a component, or `robot` for `PodPerRobot`). `_` is in no Kubernetes
    name, so two systems never share a lock."""
    return f"{namespace}_{system}_{part}.lock"


def cache_name(namespace: str, system: str) -> str:
    return f"{namespace}_{system}"


def canonical(value: Any) -> bytes:
    """The bytes the seal covers: one spelling per value."""
    return json.dumps(value, sort_keys=True, separators=(",", ":"), ensure_ascii=True).encode()


def file_digest(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def seal(manifest_bytes: bytes, key: bytes) -> str:
    """The robot's keyed digest of a manifest; the manifest lists each file's digest."""
    return hmac.new(key, manifest_bytes, hashlib.sha256).hexdigest()


@dataclass(frozen=True)
class CacheManifest:
    """What a robot last ran for one system: enough to run it again without the API server."""

    namespace: str
    system: str
    instance: str
    instance_uid: str
    robot: str
    revision: str
    recorded_at: str
    interrupt_running_trees: bool
    pods: list[dict[str, Any]]
    """Static pod manifests, ready for the kubelet."""
    files: dict[str, str]
    """Relative path under `files/` -> sha256 of its content."""
    images: dict[str, str]
    """`pod/container` -> the image ID the robot's runtime ran."""

    def to_json(self) -> dict[str, Any]:
        return {
            "format": FORMAT,
            "namespace": self.namespace,
            "system": self.system,
            "instance": self.instance,
            "instanceUid": self.instance_uid,
            "robot": self.robot,
            "revision": self.revision,
            "recordedAt": self.recorded_at,
            "interruptRunningTrees": self.interrupt_running_trees,
            "pods": self.pods,
            "files": self.files,
            "images": self.images,
        }

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> CacheManifest:
        if data.get("format") != FORMAT:
            raise ValueError(f"unknown cache format {data.get('format')!r}")
        return cls(
            namespace=data["namespace"],
            system=data["system"],
            instance=data["instance"],
            instance_uid=data["instanceUid"],
            robot=data["robot"],
            revision=data["revision"],
            recorded_at=data["recordedAt"],
            interrupt_running_trees=bool(data["interruptRunningTrees"]),
            pods=list(data["pods"]),
            files=dict(data["files"]),
            images=dict(data["images"]),
        )


@dataclass(frozen=True)
class Verdict:
    """The integrity check of one stored cache."""

    manifest: CacheManifest | None
    """Set when the cache may run."""
    reason: str = ""
    """Why it may not, for the robot's report."""


def check(
    *, manifest_bytes: bytes, stored_seal: str, key: bytes, files: dict[str, bytes], robot: str
) -> Verdict:
    """Whether a stored cache is exactly what the agent recorded, for this robot.

    `files` is every file found under `files/` (relative path -> content): one more, one fewer or
    one changed byte refuses the cache, as does a manifest whose seal does not match.
    """
    if not hmac.compare_digest(seal(manifest_bytes, key), stored_seal.strip()):
        return Verdict(None, "the manifest does not match its seal (altered, or sealed by another key)")
    try:
        manifest = CacheManifest.from_json(json.loads(manifest_bytes))
    except (ValueError, KeyError, TypeError) as error:
        return Verdict(None, f"the manifest cannot be read: {error}")
    if manifest.robot != robot:
        return Verdict(None, f"the cache was recorded for robot {manifest.robot!r}, not {robot!r}")
    extra = sorted(set(files) - set(manifest.files))
    if extra:
        return Verdict(None, f"files not in the manifest: {', '.join(extra)}")
    for path, digest in sorted(manifest.files.items()):
        if path not in files:
            return Verdict(None, f"file {path} is missing")
        if file_digest(files[path]) != digest:
            return Verdict(None, f"file {path} was altered (its digest does not match the manifest)")
    if not manifest.pods:
        return Verdict(None, "the manifest lists no pod")
    return Verdict(manifest)


class BootAction(StrEnum):
    """What the agent does with one system at boot."""

    ONLINE = "Online"
    """The API server answered: the kubelet gets its pods from it."""
    RUN = "RunOffline"
    REFUSE = "Refused"
    NOTHING = "NoRevision"


def boot_actions(*, api_reachable: bool, verdicts: dict[str, Verdict]) -> dict[str, BootAction]:
    """At boot, per stored cache: run it offline only when the API server is out of reach and the
    cache passed its check. No stored cache at all gives `{"": NOTHING}`."""
    if api_reachable:
        return {name: BootAction.ONLINE for name in verdicts} or {"": BootAction.ONLINE}
    if not verdicts:
        return {"": BootAction.NOTHING}
    return {
        name: BootAction.RUN if verdict.manifest is not None else BootAction.REFUSE
        for name, verdict in verdicts.items()
    }


class HandOver(StrEnum):
    KEEP = "Keep"
    """Keep the offline copy: no API server yet, or its tree runs and may not be interrupted."""
    HAND_OVER = "HandOver"
    """Remove the offline copy; the API server's pods pass their gate once it has stopped."""


def hand_over(*, api_reachable: bool, tree_running: bool, interrupt_running_trees: bool) -> HandOver:
    """When the offline copy of a system gives way to the API server's copy.

    The rollout's update lock applies as to any revision change: a tree still running offline is
    not interrupted unless the system's rollout says so; its pods hand over once the tree ends.
    """
    if not api_reachable:
        return HandOver.KEEP
    if tree_running and not interrupt_running_trees:
        return HandOver.KEEP
    return HandOver.HAND_OVER
