"""The robot's offline agent: a host service beside the kubelet (docs/offline.md).

`boot` runs once before the kubelet starts: when the API server does not answer, each sealed cache
that passes its check becomes static pods; one that fails is refused, with the reason kept for the
report. `watch` then runs for the robot's life: while online it records what the robot runs (pods
of systems whose pods carry the offline label, once all of them run), and when the API server is
back after an offline boot it removes the static copies under the rollout's update lock and
reports what happened, on the robot's Node and as Events on the CoralInstances.

It talks to the API server with the kubelet's own identity (the Node authorizer lets a node read
the pods bound to it and the ConfigMaps they mount, annotate its own Node and write Events), so it
needs no credential of its own.
"""

from __future__ import annotations

import datetime
import fcntl
import json
import logging
import os
import shutil
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from coral_core import names, offline
from coral_core.component_image import COMPONENT_UID

from coral.offline import store
from coral.offline.staticpods import part_of, static_copy

LOG = logging.getLogger("coral.offline")
API_TIMEOUT_S = 2.0
AGENT = "coral-offline-agent"
RECORD_EVERY = 5
FORGET_AFTER_S = 30.0
FILE_SEPARATOR = "+"
"""Between a cache's name and a pod's index in a static pod file's name: in no Kubernetes name."""


def now_text() -> str:
    return datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%dT%H:%M:%SZ")


def summarize_run(lines: list[str]) -> dict[str, Any]:
    """What an offline executor's status records say about its tree: the last status record's root
    status and tick count, and when the tree first and last ticked."""
    last: dict[str, Any] | None = None
    first_ts: float | None = None
    for line in lines:
        try:
            record = json.loads(line)
        except ValueError:
            continue
        if record.get("event") != "status":
            continue
        last = record
        if first_ts is None:
            first_ts = record.get("ts")
    if last is None:
        return {"ticked": False}
    return {
        "ticked": True,
        "rootStatus": last.get("root_status"),
        "tickCount": last.get("tick_count"),
        "activePath": last.get("active_path") or "",
        "firstStatusAt": first_ts,
        "lastStatusAt": last.get("ts"),
    }


def report_message(entry: dict[str, Any]) -> tuple[str, str, str]:
    """(event type, reason, message) of one system's boot outcome."""
    action = entry["action"]
    if action == offline.BootAction.RUN:
        run = entry.get("run") or {}
        tree = (
            f"its tree was {run['rootStatus']} at tick {run['tickCount']}"
            if run.get("ticked")
            else "its tree never ticked"
        )
        handed = entry.get("handedOverAt", "not yet")
        return (
            "Normal",
            "RanOffline",
            f"Booted without the API server at {entry['bootedAt']} and ran revision {entry['revision']} "
            f"offline; {tree}; handed over to the API server's pods at {handed}.",
        )
    if action == offline.BootAction.REFUSE:
        return (
            "Warning",
            "OfflineCacheRefused",
            f"Booted without the API server at {entry['bootedAt']} and refused to run the stored revision "
            f"offline: {entry['reason']}.",
        )
    return (
        "Warning",
        "NoRevisionOffline",
        f"Booted without the API server at {entry['bootedAt']} with no stored revision: ran nothing offline.",
    )


@dataclass
class Agent:
    robot: str
    kubeconfig: Path
    root: Path = Path(offline.ROOT)
    static_dir: Path = Path(offline.STATIC_POD_DIR)
    _api: Any = field(default=None, repr=False)
    _absent: dict[str, float] = field(default_factory=dict, repr=False)
    """Since when (monotonic) each stored system has had no pod on the robot."""

    # ---- the API server ----------------------------------------------------------------------

    def _client(self) -> Any:
        if self._api is None:
            from kubernetes import client, config

            configuration = client.Configuration()
            config.load_kube_config(config_file=str(self.kubeconfig), client_configuration=configuration)
            # One quick try: an unreachable API server must not hold the robot's boot.
            configuration.retries = False
            self._api = client.ApiClient(configuration)
            self._api.user_agent = AGENT
        return self._api

    def api_reachable(self) -> bool:
        from kubernetes import client

        try:
            client.VersionApi(self._client()).get_code(_request_timeout=API_TIMEOUT_S)
        except Exception:  # noqa: BLE001 - any failure means "not reachable now"
            return False
        return True

    # ---- boot --------------------------------------------------------------------------------

    def _static_files(self, cache: str | None = None) -> list[Path]:
        prefix = offline.STATIC_POD_PREFIX + (f"{cache}{FILE_SEPARATOR}" if cache else "")
        if not self.static_dir.is_dir():
            return []
        return sorted(p for p in self.static_dir.iterdir() if p.name.startswith(prefix))

    def boot(self) -> dict[str, Any]:
        """Runs before the kubelet: hands the verified caches to it when the API server is out of reach."""
        self.static_dir.mkdir(parents=True, exist_ok=True)
        # A copy left by an earlier offline boot is never reused unchecked.
        for stale in self._static_files():
            stale.unlink()
        reachable = self.api_reachable()
        key = store.robot_key(self.root)
        verdicts = {name: store.verify(self.root, name, key, self.robot) for name in store.caches(self.root)}
        actions = offline.boot_actions(api_reachable=reachable, verdicts=verdicts)
        booted = now_text()
        systems: dict[str, Any] = {}
        for name, action in actions.items():
            entry: dict[str, Any] = {"action": action.value, "bootedAt": booted}
            verdict = verdicts.get(name)
            manifest = verdict.manifest if verdict else None
            stored = store.read_manifest_loosely(self.root, name) if name else {}
            entry |= {k: stored.get(k) for k in ("namespace", "instance", "instanceUid", "revision")}
            if action == offline.BootAction.RUN and manifest is not None:
                self._start_offline(name, manifest)
            elif action == offline.BootAction.REFUSE and verdict is not None:
                entry["reason"] = verdict.reason
                LOG.warning("refusing to run %s offline: %s", name, verdict.reason)
            systems[name] = entry
        report = {"robot": self.robot, "bootedAt": booted, "apiReachable": reachable, "systems": systems}
        report["reported"] = reachable
        store.write_json(self.root / Path(offline.REPORT_FILE).name, report)
        return report

    def _start_offline(self, cache: str, manifest: offline.CacheManifest) -> None:
        run_dir = self.root / Path(offline.RUNS_DIR).name / cache
        shutil.rmtree(run_dir, ignore_errors=True)
        run_dir.mkdir(parents=True)
        # The offline executor runs as the components' user and appends its status records here.
        if os.geteuid() == 0:
            os.chown(run_dir, COMPONENT_UID, COMPONENT_UID)
        (self.root / Path(offline.LOCKS_DIR).name).mkdir(parents=True, exist_ok=True)
        for index, pod in enumerate(manifest.pods):
            target = self.static_dir / f"{offline.STATIC_POD_PREFIX}{cache}{FILE_SEPARATOR}{index}.json"
            store.write_json(target, pod)
        LOG.info("running revision %s of %s offline (%d pods)", manifest.revision, cache, len(manifest.pods))

    # ---- watching ----------------------------------------------------------------------------

    def tree_running(self, cache: str) -> bool:
        """Whether an offline executor of `cache` still runs: its pod's lock holder keeps the lock
        until the pod's containers have stopped, and stops once the tree has ended."""
        for path in self._static_files(cache):
            pod = json.loads(path.read_text())
            labels = pod["metadata"].get("labels", {})
            if labels.get(names.LABEL_ROLE, "executor") != "executor":
                continue
            lock = (
                self.root
                / Path(offline.LOCKS_DIR).name
                / offline.lock_name(
                    pod["metadata"]["namespace"], labels.get(names.LABEL_SYSTEM, ""), part_of(pod)
                )
            )
            if lock.exists() and lock_held(lock):
                return True
        return False

    def step(self, record: bool = True) -> None:
        """One pass of the watch loop; `record` also records what runs."""
        reachable = self.api_reachable()
        report_path = self.root / Path(offline.REPORT_FILE).name
        report = store.read_json(report_path)
        handed = False
        for cache in {
            p.name[len(offline.STATIC_POD_PREFIX) :].rpartition(FILE_SEPARATOR)[0]
            for p in self._static_files()
        }:
            manifest = store.read_manifest_loosely(self.root, cache)
            decision = offline.hand_over(
                api_reachable=reachable,
                tree_running=self.tree_running(cache),
                interrupt_running_trees=bool(manifest.get("interruptRunningTrees")),
            )
            if decision == offline.HandOver.HAND_OVER:
                self._hand_over(cache, report)
                handed = True
        if handed and report is not None:
            store.write_json(report_path, report)
        if not reachable:
            return
        if report is not None and not report.get("reported") and not self._static_files():
            self._send_report(report)
            report["reported"] = True
            store.write_json(report_path, report)
        if record:
            self.record()

    def _hand_over(self, cache: str, report: dict[str, Any] | None) -> None:
        status = self.root / Path(offline.RUNS_DIR).name / cache / offline.STATUS_FILE
        lines = status.read_text(errors="replace").splitlines() if status.exists() else []
        for path in self._static_files(cache):
            path.unlink()
        LOG.info("handed %s over to the API server's pods", cache)
        if report is not None and cache in report.get("systems", {}):
            report["systems"][cache] |= {"handedOverAt": now_text(), "run": summarize_run(lines)}

    def _send_report(self, report: dict[str, Any]) -> None:
        from kubernetes import client

        core = client.CoreV1Api(self._client())
        summary = {
            name: {k: v for k, v in entry.items() if k in ("action", "revision", "reason", "handedOverAt")}
            for name, entry in report.get("systems", {}).items()
        }
        body = json.dumps({"bootedAt": report.get("bootedAt"), "systems": summary}, sort_keys=True)
        try:
            core.patch_node(self.robot, {"metadata": {"annotations": {offline.ANNOTATION_NODE_REPORT: body}}})
        except Exception as error:  # noqa: BLE001 - the Events below still tell
            LOG.warning("could not annotate Node %s: %s", self.robot, error)
        for entry in report.get("systems", {}).values():
            kind, reason, message = report_message(entry)
            if entry.get("instance"):
                involved = client.V1ObjectReference(
                    api_version=names.API_VERSION,
                    kind=names.INSTANCE_KIND,
                    name=entry["instance"],
                    namespace=entry["namespace"],
                    uid=entry.get("instanceUid"),
                )
                namespace = entry["namespace"]
            else:
                involved = client.V1ObjectReference(api_version="v1", kind="Node", name=self.robot)
                namespace = "default"
            self._event(core, namespace, involved, kind, reason, message)

    def _event(self, core: Any, namespace: str, involved: Any, kind: str, reason: str, message: str) -> None:
        from kubernetes import client

        stamp = datetime.datetime.now(datetime.UTC)
        event = client.CoreV1Event(
            metadata=client.V1ObjectMeta(generate_name=f"{self.robot}.offline."),
            involved_object=involved,
            type=kind,
            reason=reason,
            message=message,
            source=client.V1EventSource(component=AGENT, host=self.robot),
            reporting_component=AGENT,
            reporting_instance=self.robot,
            first_timestamp=stamp,
            last_timestamp=stamp,
            count=1,
        )
        try:
            core.create_namespaced_event(namespace, event)
        except Exception as error:  # noqa: BLE001 - the Node's annotation still tells
            LOG.warning("could not write Event %s: %s", reason, error)

    # ---- recording ---------------------------------------------------------------------------

    def record(self) -> list[str]:
        """Records each offline-enabled system whose pods all run on this robot; returns those
        recorded anew."""
        from kubernetes import client

        api = self._client()
        core = client.CoreV1Api(api)
        pods = core.list_pod_for_all_namespaces(
            field_selector=f"spec.nodeName={self.robot}",
            label_selector=f"{offline.LABEL_OFFLINE},{names.LABEL_INSTANCE}",
            _request_timeout=10,
        )
        groups: dict[str, list[dict[str, Any]]] = {}
        for pod in pods.items:
            wire = api.sanitize_for_serialization(pod)
            labels = wire["metadata"].get("labels", {})
            groups.setdefault(
                offline.cache_name(wire["metadata"]["namespace"], labels[names.LABEL_SYSTEM]), []
            ).append(wire)
        self._forget_absent(set(groups))
        recorded: list[str] = []
        for cache, members in sorted(groups.items()):
            if not store.all_running(members):
                continue
            fingerprint = store.fingerprint(members)
            if store.read_text(self.root, cache, store.SOURCE_FILE) == fingerprint:
                continue
            namespace = members[0]["metadata"]["namespace"]
            config_maps = {
                name: dict(core.read_namespaced_config_map(name, namespace, _request_timeout=10).data or {})
                for name in store.config_map_names(members)
            }
            self._record(cache, members, config_maps, fingerprint)
            recorded.append(cache)
        return recorded

    def _forget_absent(self, present: set[str]) -> None:
        """Drops the cache of a system that has had no pod on the robot for a while: deleted, moved
        off this robot, or with offline turned off. Not at once: a rollout replaces pods."""
        now = time.monotonic()
        for cache in store.caches(self.root):
            if cache in present:
                self._absent.pop(cache, None)
                continue
            since = self._absent.setdefault(cache, now)
            if now - since >= FORGET_AFTER_S:
                shutil.rmtree(self.root / Path(offline.CACHES_DIR).name / cache, ignore_errors=True)
                self._absent.pop(cache, None)
                LOG.info("forgot %s: none of its pods is on this robot any more", cache)

    def _record(
        self,
        cache: str,
        members: list[dict[str, Any]],
        config_maps: dict[str, dict[str, str]],
        fingerprint: str,
    ) -> None:
        folder = self.root / Path(offline.CACHES_DIR).name / cache
        run_dir = str(Path(offline.RUNS_DIR) / cache)
        files: dict[str, bytes] = {}
        pods: list[dict[str, Any]] = []
        images: dict[str, str] = {}
        for pod in sorted(members, key=lambda p: p["metadata"]["name"]):
            copy = static_copy(
                pod,
                config_maps=config_maps,
                files_dir=str(Path(offline.CACHES_DIR) / cache / offline.FILES_DIR / part_of(pod)),
                run_dir=run_dir,
            )
            pods.append(copy.pod)
            files |= {f"{part_of(pod)}/{path}": data for path, data in copy.files.items()}
            status = pod.get("status") or {}
            for container in [
                *(status.get("initContainerStatuses") or []),
                *(status.get("containerStatuses") or []),
            ]:
                images[f"{part_of(pod)}/{container['name']}"] = container.get("imageID") or container["image"]
        first = members[0]["metadata"]
        labels = first.get("labels", {})
        manifest = offline.CacheManifest(
            namespace=first["namespace"],
            system=labels[names.LABEL_SYSTEM],
            instance=labels[names.LABEL_INSTANCE],
            instance_uid=next((o["uid"] for o in first.get("ownerReferences") or []), ""),
            robot=self.robot,
            revision=labels.get(names.LABEL_REVISION, ""),
            recorded_at=now_text(),
            interrupt_running_trees=first.get("annotations", {}).get(offline.ANNOTATION_INTERRUPT) == "true",
            pods=pods,
            files={path: offline.file_digest(data) for path, data in files.items()},
            images=images,
        )
        store.write_cache(folder, manifest, files, store.robot_key(self.root), fingerprint)
        LOG.info("recorded revision %s of %s", manifest.revision, cache)

    def watch(self, interval: float = 1.0, record_every: int = RECORD_EVERY) -> None:
        passes = 0
        while True:
            started = time.monotonic()
            try:
                # The hand-over is checked every pass; recording (a list of the robot's pods) less often.
                self.step(record=passes % record_every == 0)
                passes += 1
            except Exception:  # noqa: BLE001 - one bad pass must not end the robot's agent
                LOG.exception("offline agent pass failed")
            time.sleep(max(0.0, interval - (time.monotonic() - started)))


def lock_held(path: Path) -> bool:
    """Whether another process holds `path`'s lock (taking it for a moment when it is free)."""
    with path.open("a") as handle:
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            return True
        fcntl.flock(handle, fcntl.LOCK_UN)
        return False
