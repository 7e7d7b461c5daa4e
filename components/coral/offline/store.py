"""The robot's offline cache on disk: one sealed folder per system (docs/offline.md).

    <root>/key                           32 random bytes, root only: the robot's sealing key
    <root>/systems/<namespace>_<system>/ manifest.json, seal, source, files/...
    <root>/runs/<namespace>_<system>/    status.jsonl of the offline executor
    <root>/locks/                        one lock file per component
    <root>/report.json                   the last boot's outcome

A cache is written aside and renamed into place, so a robot losing power mid-write keeps the
previous one whole. The check itself is `coral_core.offline.check`.
"""

from __future__ import annotations

import hashlib
import json
import os
import secrets
import shutil
from pathlib import Path
from typing import Any

from coral_core import names, offline

SOURCE_FILE = "source"
"""The API pods a cache was recorded from (names and pod hashes): recorded again only on change."""
KEY_BYTES = 32


def robot_key(root: Path) -> bytes:
    """The robot's sealing key, made on first use; readable by root only."""
    path = root / Path(offline.KEY_FILE).name
    if not path.exists():
        root.mkdir(parents=True, exist_ok=True)
        aside = path.with_suffix(".tmp")
        descriptor = os.open(aside, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
        with os.fdopen(descriptor, "wb") as handle:
            handle.write(secrets.token_bytes(KEY_BYTES))
        aside.replace(path)
    return path.read_bytes()


def caches(root: Path) -> list[str]:
    folder = root / Path(offline.CACHES_DIR).name
    if not folder.is_dir():
        return []
    return sorted(p.name for p in folder.iterdir() if p.is_dir() and not p.name.startswith("."))


def _files(folder: Path) -> dict[str, bytes]:
    if not folder.is_dir():
        return {}
    return {
        path.relative_to(folder).as_posix(): path.read_bytes()
        for path in sorted(folder.rglob("*"))
        if path.is_file() or path.is_symlink()
    }


def verify(root: Path, cache: str, key: bytes, robot: str) -> offline.Verdict:
    """The check of one stored cache; a missing part refuses it like an altered one."""
    folder = root / Path(offline.CACHES_DIR).name / cache
    try:
        manifest_bytes = (folder / offline.MANIFEST_FILE).read_bytes()
        stored_seal = (folder / offline.SEAL_FILE).read_text()
    except OSError as error:
        return offline.Verdict(
            None, f"the cache is incomplete: {error.strerror} ({Path(error.filename).name})"
        )
    return offline.check(
        manifest_bytes=manifest_bytes,
        stored_seal=stored_seal,
        key=key,
        files=_files(folder / offline.FILES_DIR),
        robot=robot,
    )


def read_manifest_loosely(root: Path, cache: str) -> dict[str, Any]:
    """The stored manifest unchecked, for naming what was refused and where to report it."""
    path = root / Path(offline.CACHES_DIR).name / cache / offline.MANIFEST_FILE
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def read_text(root: Path, cache: str, name: str) -> str | None:
    try:
        return (root / Path(offline.CACHES_DIR).name / cache / name).read_text()
    except OSError:
        return None


def write_json(path: Path, value: Any) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    aside = path.with_name(f".{path.name}.tmp")
    aside.write_text(json.dumps(value, indent=1, sort_keys=True))
    aside.replace(path)


def read_json(path: Path) -> Any:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


def write_cache(
    folder: Path, manifest: offline.CacheManifest, files: dict[str, bytes], key: bytes, source: str
) -> None:
    """Writes a sealed cache aside and swaps it in."""
    aside = folder.with_name(f".{folder.name}.new")
    old = folder.with_name(f".{folder.name}.old")
    for leftover in (aside, old):
        shutil.rmtree(leftover, ignore_errors=True)
    for path, data in files.items():
        target = aside / offline.FILES_DIR / path
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_bytes(data)
    manifest_bytes = offline.canonical(manifest.to_json())
    (aside / offline.MANIFEST_FILE).write_bytes(manifest_bytes)
    (aside / offline.SEAL_FILE).write_text(offline.seal(manifest_bytes, key))
    (aside / SOURCE_FILE).write_text(source)
    if folder.exists():
        folder.replace(old)
    aside.replace(folder)
    shutil.rmtree(old, ignore_errors=True)


def all_running(pods: list[dict[str, Any]]) -> bool:
    """Whether a system's pods on the robot are what it runs now: one revision, none deleting, each
    Running (an executor whose mission ended is Succeeded) with every container started."""
    revisions = {p["metadata"].get("labels", {}).get(names.LABEL_REVISION) for p in pods}
    if len(revisions) != 1:
        return False
    for pod in pods:
        if pod["metadata"].get("deletionTimestamp"):
            return False
        status = pod.get("status") or {}
        phase = status.get("phase")
        if phase == "Succeeded":
            continue
        if phase != "Running":
            return False
        if not all(c.get("started") or c.get("ready") for c in status.get("containerStatuses") or []):
            return False
    return True


def fingerprint(pods: list[dict[str, Any]]) -> str:
    """What a recording depends on. The owning instance's uid is part of it: a system deleted and
    made again under its name gives pods of the same names and hashes, and its cache must name the
    new instance, not the one that is gone."""
    parts = sorted(
        f"{p['metadata']['name']}={p['metadata'].get('annotations', {}).get(names.ANNOTATION_POD_HASH, '')}"
        f"@{','.join(o.get('uid', '') for o in p['metadata'].get('ownerReferences') or [])}"
        for p in pods
    )
    return hashlib.sha256("\n".join(parts).encode()).hexdigest()


def config_map_names(pods: list[dict[str, Any]]) -> list[str]:
    """Every ConfigMap the pods' volumes show (plain or projected)."""
    found: set[str] = set()
    for pod in pods:
        for volume in pod["spec"].get("volumes") or []:
            if "configMap" in volume:
                found.add(volume["configMap"]["name"])
            sources = (volume.get("projected") or {}).get("sources") or []
            # A volume with a token is dropped from the offline copy, its ConfigMaps with it.
            if all(set(source) == {"configMap"} for source in sources):
                found |= {source["configMap"]["name"] for source in sources}
    return sorted(found)
