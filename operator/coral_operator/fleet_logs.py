"""The logs of a CoralSystem's robots, as `coral logs SYSTEM` prints them: every component container
of every pod of the system, read through the API server, each line prefixed with its robot and
component.

The pure part (which containers are components, the prefix and its colours, `--since`) is apart
from `follow`, which reads one log stream per container on its own thread and prints from one
thread, so lines stay in order per container while containers interleave. Called by `logs_cli`.
"""

from __future__ import annotations

import queue
import re
import threading
import zlib
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass
from typing import Any

import click
from coral_core import names
from kubernetes import client as k8s
from kubernetes import watch as k8s_watch
from kubernetes.client.exceptions import ApiException

from coral_operator.planning import naming
from coral_operator.planning.pods import FOLDERS_OWNER

# Foreground colours that read on dark and light terminals, as stern picks from.
PALETTE = ("cyan", "green", "magenta", "yellow", "blue", "bright_cyan", "bright_green", "bright_magenta")
_SINCE = re.compile(r"(\d+)([smhd])")
_UNIT_S = {"s": 1, "m": 60, "h": 3600, "d": 86400}


class LogsError(Exception):
    """The logs cannot be read that way; the message says why."""


@dataclass(frozen=True)
class Stream:
    """One component container's log: `robot` and `component` make its prefix."""

    pod: str
    container: str
    robot: str
    component: str
    container_id: str
    """The container's current instance: a restarted container is a new stream."""


def parse_since(text: str) -> int:
    """`--since` as seconds: a sum of `<n>s`, `<n>m`, `<n>h`, `<n>d` (`90s`, `1h30m`).

    Raises:
        ValueError: anything else, or zero.
    """
    parts = _SINCE.findall(text)
    if not parts or "".join(n + u for n, u in parts) != text:
        raise ValueError(f"{text!r} is not a duration like 30s, 5m, 1h30m or 2d")
    seconds = sum(int(n) * _UNIT_S[u] for n, u in parts)
    if seconds <= 0:
        raise ValueError(f"{text!r} is no time at all")
    return seconds


def _started_id(status: Mapping[str, Any] | None) -> str | None:
    """The id of a container that has a log to read (running or finished), else None."""
    if not status or not (status.get("state") or {}).keys() & {"running", "terminated"}:
        return None
    return str(status.get("containerID") or "")


def streams_of(pods: Iterable[Mapping[str, Any]], component: str | None) -> list[Stream]:
    """The log streams of `pods` (API dicts, camelCase), ordered by robot then component.

    A component is a container (a pod per component has one, a pod per robot one per component,
    drivers and skillsets as native sidecars); the helper that prepares shared folders is not one.
    Containers that have not started have no log yet and are left out.
    """
    found: list[Stream] = []
    for pod in pods:
        meta, spec, status = pod["metadata"], pod.get("spec") or {}, pod.get("status") or {}
        robot = (meta.get("labels") or {}).get(names.LABEL_ROBOT) or spec.get("nodeName") or "?"
        declared = [
            *(c["name"] for c in spec.get("initContainers") or [] if c.get("restartPolicy") == "Always"),
            *(c["name"] for c in spec.get("containers") or []),
        ]
        statuses = {
            s["name"]: s
            for s in [*(status.get("initContainerStatuses") or []), *(status.get("containerStatuses") or [])]
        }
        for container in declared:
            started = _started_id(statuses.get(container))
            if container == FOLDERS_OWNER or started is None or component not in (None, container):
                continue
            found.append(Stream(meta["name"], container, robot, container, started))
    return sorted(found, key=lambda s: (s.robot, s.component, s.pod))


def colour_of(text: str) -> str:
    """The colour `text` always gets (the same robot reads the same in every run)."""
    return PALETTE[zlib.crc32(text.encode()) % len(PALETTE)]


def prefixed(stream: Stream, line: str, width: int, colour: bool) -> str:
    """`robot/component | line`, the prefix padded to `width` and coloured by robot and component
    when printing to a terminal; plain text otherwise, so a pipe gets no escape codes."""
    plain = f"{stream.robot}/{stream.component}"
    pad = " " * max(0, width - len(plain))
    if not colour:
        return f"{plain}{pad} | {line}"
    robot = click.style(stream.robot, fg=colour_of(stream.robot), bold=True)
    component = click.style(stream.component, fg=colour_of(stream.component))
    return f"{robot}/{component}{pad} | {line}"


def lines_of(response: Any) -> Iterator[str]:
    """The lines of a streamed log response as they arrive; a partial last line is kept until its
    end comes (or the stream ends)."""
    pending = b""
    for chunk in response.stream(amt=65536, decode_content=True):
        pending += chunk
        *complete, pending = pending.split(b"\n")
        for raw in complete:
            yield raw.decode("utf-8", errors="replace").rstrip("\r")
    if pending:
        yield pending.decode("utf-8", errors="replace").rstrip("\r")


@dataclass
class FleetLogs:
    """Reads the logs of one system's pods. `print_line` is called from the calling thread only."""

    api_client: k8s.ApiClient
    namespace: str
    system: str
    robot: str | None = None
    component: str | None = None
    since_s: int | None = None

    def _selector(self) -> str:
        selector = f"{names.LABEL_SYSTEM}={naming.label_value(self.system)}"
        if self.robot:
            selector += f",{names.LABEL_ROBOT}={naming.label_value(self.robot)}"
        return selector

    def check_system(self) -> None:
        """Raises LogsError when the namespace has no such CoralSystem."""
        try:
            k8s.CustomObjectsApi(self.api_client).get_namespaced_custom_object(
                names.GROUP, names.VERSION, self.namespace, names.SYSTEM_PLURAL, self.system
            )
        except ApiException as error:
            if error.status == 404:
                raise LogsError(
                    f"coralsystem/{self.system} not found in namespace {self.namespace}"
                ) from error
            raise

    def _pods(self) -> tuple[list[dict[str, Any]], str]:
        listed = k8s.CoreV1Api(self.api_client).list_namespaced_pod(
            self.namespace, label_selector=self._selector()
        )
        pods = [self.api_client.sanitize_for_serialization(p) for p in listed.items]
        return pods, listed.metadata.resource_version

    def _read(self, stream: Stream, follow: bool, out: queue.Queue[tuple[Stream, str | None]]) -> None:
        """Puts the stream's lines on `out`, then (stream, None) when it ended."""
        try:
            response = k8s.CoreV1Api(self.api_client).read_namespaced_pod_log(
                stream.pod,
                self.namespace,
                container=stream.container,
                follow=follow,
                since_seconds=self.since_s,
                _preload_content=False,
            )
            try:
                for line in lines_of(response):
                    out.put((stream, line))
            finally:
                response.release_conn()
        except ApiException as error:
            # The pod went away meanwhile: the others go on.
            out.put((stream, f"[coral logs: cannot read this log: {error.reason}]"))
        except Exception as error:  # noqa: BLE001 - a dropped connection ends this stream, not the others
            out.put((stream, f"[coral logs: the log stream ended: {error}]"))
        out.put((stream, None))

    def _start(self, stream: Stream, follow: bool, out: queue.Queue[tuple[Stream, str | None]]) -> None:
        threading.Thread(target=self._read, args=(stream, follow, out), daemon=True, name=stream.pod).start()

    def _start_new(
        self, pods: list[dict[str, Any]], known: set[Stream], out: queue.Queue[tuple[Stream, str | None]]
    ) -> None:
        """Starts a followed stream for every container of `pods` not read yet (a new or restarted one)."""
        for stream in streams_of(pods, self.component):
            if stream not in known:
                known.add(stream)
                self._start(stream, True, out)

    def _watch_pods(
        self, resource_version: str, known: set[Stream], out: queue.Queue[tuple[Stream, str | None]]
    ) -> None:
        """Follows the system's pods, so containers that start later are read too. Runs on its own
        thread, the only one that changes `known` once `run` started it."""
        core = k8s.CoreV1Api(self.api_client)
        retry = threading.Event()
        while True:
            try:
                for event in k8s_watch.Watch().stream(
                    core.list_namespaced_pod,
                    self.namespace,
                    label_selector=self._selector(),
                    resource_version=resource_version,
                ):
                    pod = self.api_client.sanitize_for_serialization(event["object"])
                    resource_version = pod["metadata"].get("resourceVersion", resource_version)
                    self._start_new([pod], known, out)
            except Exception:  # noqa: BLE001 - an expired or dropped watch: start over from a fresh list
                try:
                    pods, resource_version = self._pods()
                except Exception:  # noqa: BLE001 - the API server is out of reach: try again shortly
                    retry.wait(1.0)
                    continue
                self._start_new(pods, known, out)

    def run(self, follow: bool, print_line: Callable[[Stream, str], None]) -> int:
        """Prints every stream's lines as they come; returns the number of streams read.

        Without `follow` it returns when every log was read; with it, it runs until interrupted
        (KeyboardInterrupt reaches the caller), picking up containers that start meanwhile.
        """
        pods, resource_version = self._pods()
        streams = streams_of(pods, self.component)
        out: queue.Queue[tuple[Stream, str | None]] = queue.Queue()
        for stream in streams:
            self._start(stream, follow, out)
        if follow:
            threading.Thread(
                target=self._watch_pods, args=(resource_version, set(streams), out), daemon=True, name="pods"
            ).start()
        open_streams = len(streams)
        while follow or open_streams:
            stream, line = out.get()
            if line is None:
                open_streams -= 1
            else:
                print_line(stream, line)
        return len(streams)
