"""Which pods and Nodes the operator watches, as kopf label filters and as server-side selectors.

kopf filters its handlers' labels in the operator, after every event of the resource has been
sent and decoded; the same labels as a watch's `labelSelector` keep the API server from sending
the rest at all. In a shared cluster that is most pods and Nodes: without it, the operator would
decode every pod of every other application in the namespaces it serves (a pod event is about
10 kB of JSON) and every non-robot Node's heartbeat.
"""

from __future__ import annotations

from typing import Any

import kopf
from coral_core import names

CORAL_POD_LABELS: dict[str, Any] = {names.LABEL_MANAGED_BY: names.MANAGER, names.LABEL_INSTANCE: kopf.PRESENT}
ROBOT_NODE_LABELS: dict[str, Any] = {names.LABEL_ROBOT: kopf.PRESENT}
# Filtered in the operator only: the ConfigMap watch also serves the systems' source files.
REVISION_CONFIG_MAP_LABELS: dict[str, Any] = {
    names.LABEL_MANAGED_BY: names.MANAGER,
    names.LABEL_SYSTEM: kopf.PRESENT,
}


def label_selector(labels: dict[str, Any]) -> str:
    """A kopf label filter as a Kubernetes label selector (kopf.PRESENT: the label exists)."""
    return ",".join(
        key if value is kopf.PRESENT else f"{key}={value}" for key, value in sorted(labels.items())
    )


def watch_selectors() -> dict[tuple[str, str], str]:
    """The server-side selector of each filtered resource, keyed as kopf's settings take them."""
    return {
        ("v1", "pods"): label_selector(CORAL_POD_LABELS),
        ("v1", "nodes"): label_selector(ROBOT_NODE_LABELS),
    }
