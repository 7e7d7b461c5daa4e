"""Immutable ConfigMaps holding the validated tree and parameters of one revision.

Named by content hash, so a revision keeps pointing at exactly what was validated: editing a
source ConfigMap into something broken never changes what robots run. Pure; called by the system
handler, applied by `kube.applying`.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from coral_core import names
from coral_core.names import API_VERSION

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


def source_refusal(field: str, name: str, labels: Mapping[str, str] | None) -> str | None:
    """Why a system may not read the ConfigMap `name` it names at `field`; None when it may (or when
    the ConfigMap is missing, which the caller reports).

    The operator can read every ConfigMap and copies what it reads into the system's pods, so
    reading one for anyone who may write a CoralSystem would hand them ConfigMaps they may not
    read (a confused deputy; issue 47, item 9). Its owners' label is the consent.
    """
    if labels is None or labels.get(names.LABEL_SOURCE) == "true":
        return None
    return (
        f"{field}: ConfigMap {name} is not marked as a Coral source; the operator reads only "
        f'ConfigMaps labelled {names.LABEL_SOURCE}: "true" by those who may write them.'
    )
