"""Runs the operator: loads the handlers and hands control to kopf (one replica, no peering).

Called by `python -m coral_operator` and `coral operator`.
"""

from __future__ import annotations

import importlib
import logging


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
    kopf.run(
        memo=kopf.Memo(namespaces=list(namespaces)),
        standalone=True,
        clusterwide=not namespaces,
        namespaces=namespaces,
        liveness_endpoint=liveness,
    )
