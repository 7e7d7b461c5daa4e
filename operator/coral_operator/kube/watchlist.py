"""Whether the API server streams a watch's initial objects (`sendInitialEvents`, Kubernetes' WatchList).

Streamed, a restarted operator receives the objects it serves one watch event at a time. Listed,
each namespace's page of CoralSystems comes as one response whose text and decoded objects are held
at once, every namespace at the same moment: ten namespaces of megabyte systems took the operator
past the chart's memory limit as it started (docs/architecture.md, "The operator's memory").
WatchList is on by default from Kubernetes 1.34, off in 1.33 and alpha before, and an
administrator may turn it off, so the operator asks the server rather than reading its version.
"""

from __future__ import annotations

import json
from collections.abc import Iterable

from coral_core.names import GROUP, SYSTEM_PLURAL, VERSION
from kubernetes.client.exceptions import ApiException

from coral_operator.kube import client

INITIAL_EVENTS_END = "k8s.io/initial-events-end"
"""The annotation on the bookmark that closes a watch's initial events."""

MATCHES_NOTHING = "coral.dev/initial-events-probe=never"
"""The probe's label selector: its initial events are the closing bookmark alone."""

PROBE_TIMEOUT_S = 5


def initial_events_streamed(namespace: str | None) -> bool:
    """Whether a watch of CoralSystems in `namespace` (None: all) can start with the objects
    already there. Raises for an answer that says nothing about it (the server unreachable)."""
    path = f"/apis/{GROUP}/{VERSION}/" + (f"namespaces/{namespace}/" if namespace else "") + SYSTEM_PLURAL
    api = client.api_client()
    method, url, headers, _, _ = api.param_serialize(
        method="GET",
        resource_path=path,
        query_params=[
            ("watch", "true"),
            ("sendInitialEvents", "true"),
            ("resourceVersionMatch", "NotOlderThan"),
            ("allowWatchBookmarks", "true"),
            ("labelSelector", MATCHES_NOTHING),
            ("timeoutSeconds", str(PROBE_TIMEOUT_S)),
        ],
        header_params={"Accept": "application/json"},
        auth_settings=["BearerToken"],
    )
    try:
        response = api.call_api(method, url, header_params=headers, _request_timeout=PROBE_TIMEOUT_S + 5)
    except ApiException as error:
        # 422 (the feature off, or a server that refuses resourceVersionMatch on a watch) or 400.
        if error.status in (400, 422):
            return False
        raise
    raw = response.response
    try:
        if not 200 <= response.status <= 299:
            return False
        return ends_initial_events(raw)
    finally:
        # The watch is still open after its bookmark: the connection is closed, not handed back
        # to the pool with the rest of the stream unread.
        raw.close()
        raw.release_conn()


def ends_initial_events(lines: Iterable[bytes]) -> bool:
    """Whether a watch stream's lines reach the bookmark that closes the initial events. A server
    without WatchList ignores `sendInitialEvents` and may still send plain bookmarks."""
    for line in lines:
        if not line.strip():
            continue
        try:
            event = json.loads(line)
        except ValueError:
            return False
        annotations = ((event.get("object") or {}).get("metadata") or {}).get("annotations") or {}
        if event.get("type") == "BOOKMARK" and annotations.get(INITIAL_EVENTS_END) == "true":
            return True
    return False
