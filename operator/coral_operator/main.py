"""Runs the operator: loads the handlers and hands control to kopf (one replica, no peering).

Called by `python -m coral_operator` and `coral operator`.
"""

from __future__ import annotations

import gc
import importlib
import logging
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from prometheus_client import CollectorRegistry

# Container objects allocated between two young-generation collections (CPython's default is 700).
# Every watch event decodes a whole object (a pod is about 10 kB of JSON, hundreds of dicts and
# lists), so with the default the collector ran thousands of times per fleet rollout, and each
# tenth of those promoted into full collections over everything the operator holds: at 300 robots
# that was a quarter of the operator's CPU. Reference counting still frees the decoded events at
# once; the threshold only spaces out the search for cycles.
YOUNG_COLLECTION_THRESHOLD = 50_000


def run(
    *,
    namespaces: list[str],
    verbose: bool = False,
    liveness: str | None = None,
    metrics: tuple[str, int] | None = None,
) -> None:
    """Serve the given namespaces (all of them when empty) until interrupted; with `metrics`
    (address, port), serve Prometheus metrics on http://ADDRESS:PORT/metrics (docs/metrics.md)."""
    import kopf

    logging.basicConfig(
        level=logging.DEBUG if verbose else logging.INFO,
        format="%(asctime)s %(levelname)s %(name)s: %(message)s",
    )
    # Per-object "Handler succeeded" lines (one per watch event) would drown everything else at INFO.
    logging.getLogger("kopf.objects").setLevel(logging.DEBUG if verbose else logging.WARNING)
    importlib.import_module("coral_operator.handlers")
    _tune_garbage_collector()
    registry = None if metrics is None else _serve_metrics(*metrics)
    kopf.run(
        memo=kopf.Memo(namespaces=list(namespaces), metrics_registry=registry),
        standalone=True,
        clusterwide=not namespaces,
        namespaces=namespaces,
        liveness_endpoint=liveness,
    )


def metrics_registry() -> CollectorRegistry:
    """The operator's own registry: no default collectors but the process's CPU and memory."""
    from prometheus_client import CollectorRegistry, ProcessCollector

    registry = CollectorRegistry()
    ProcessCollector(namespace="coral_operator", registry=registry)
    return registry


def _serve_metrics(address: str, port: int) -> CollectorRegistry:
    """A new `metrics_registry`, served from a thread of prometheus_client's until the process ends."""
    from prometheus_client import start_http_server

    registry = metrics_registry()
    start_http_server(port, addr=address, registry=registry)
    return registry


def _tune_garbage_collector() -> None:
    """Run once the handlers are loaded: what import created (modules, classes, pydantic's
    validators) lives as long as the process, so it leaves the collector's scans for good."""
    gc.freeze()
    _, middle, old = gc.get_threshold()
    gc.set_threshold(YOUNG_COLLECTION_THRESHOLD, middle, old)
