"""Immutable ConfigMaps holding the validated tree and parameters of one revision.

Named by content hash, so a revision keeps pointing at exactly what was validated: editing a
source ConfigMap into something broken never changes what robots run. Pure; called by the system
handler, applied by `kube.applying`.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from coral_operator.api import names
from coral_operator.api.names import API_VERSION
from coral_operator.planning import naming

TREE_KEY = "tree.xml"
PARAMS_KEY = "params.yaml"


def build_config_map(
    *,
    system: str,
    namespace: str,
    system_uid: str,
    kind: str,
    key: str,
    text: str,
    beside: Mapping[str, str] | None = None,
) -> dict[str, Any]:
    """The ConfigMap manifest of one validated file (`kind` is `tree` or `params`), with the files
    it includes `beside` it, so that they resolve on the robot as they did in validation."""
    data = {**(beside or {}), key: text}
    digest = naming.content_hash(data if beside else {key: text})
    return {
        "apiVersion": "v1",
        "kind": "ConfigMap",
        "metadata": {
            "name": naming.config_map_name(system, kind, digest),
            "namespace": namespace,
            "labels": {
                names.LABEL_SYSTEM: naming.label_value(system),
                names.LABEL_MANAGED_BY: names.MANAGER,
            },
            "ownerReferences": [naming.owner_reference(API_VERSION, names.SYSTEM_KIND, system, system_uid)],
        },
        "immutable": True,
        "data": data,
    }


def plan_config_map_cleanup(existing: list[str], in_use: set[str]) -> list[str]:
    """ConfigMaps no instance and no current revision uses any more, to delete."""
    return sorted(name for name in existing if name not in in_use)
