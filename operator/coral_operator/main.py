"""Runs the operator: loads the handlers and hands control to kopf (one replica, no peering).

Called by `python -m coral_operator` and `coral operator`.
"""

from __future__ import annotations

import gc
import importlib
import logging

# Container objects allocated between two young-generation collections (CPython's default is 700).
# Every watch event decodes a whole object (a pod is about 10 kB of JSON, hundreds of dicts and
# lists), so with the default the collector ran thousands of times per fleet rollout, and each
# tenth of those promoted into full collections over everything the operator holds: at 300 robots
# that was a quarter of the operator's CPU. Reference counting still frees the decoded events at
# once; the threshold only spaces out the search for cycles.
YOUNG_COLLECTION_THRESHOLD = 50_000


def run(*, namespaces: list[str], verbose: bool = False, liveness: str | None = None) -> None:
    """Serve the given namespaces (all of them when empty) until interrupted."""
    import kopf

    logging.basicConfig(
        level=logging.DEBUG if verbose else logging.INFO,
        format="%(asctime)s %(levelname)s %(name)s: %(message)s",
    )
    # Per-object "Handler succeeded" lines (one per watch event) would drown everything else at INFO.
    logging.getLogger("kopf.objects").setLevel(logging.DEBUG if verbose else logging.WARNING)
    importlib.import_module("coral_operator.handlers")
    _tune_garbage_collector()
    kopf.run(
        memo=kopf.Memo(namespaces=list(namespaces)),
        standalone=True,
        clusterwide=not namespaces,
        namespaces=namespaces,
        liveness_endpoint=liveness,
    )


def _tune_garbage_collector() -> None:
    """Run once the handlers are loaded: what import created (modules, classes, pydantic's
    validators) lives as long as the process, so it leaves the collector's scans for good."""
    gc.freeze()
    _, middle, old = gc.get_threshold()
    gc.set_threshold(YOUNG_COLLECTION_THRESHOLD, middle, old)
