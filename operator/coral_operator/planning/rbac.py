"""The executor's identity on one robot: a ServiceAccount whose Role allows only patching the status
of that robot's own CoralInstance (acceptance: denied for systems, pods and other robots).

A Role's `resourceNames` is the only way to scope a rule to one object, hence one account per
instance. Pure; applied by the instance handler; all three objects are owned by the instance.
"""

from __future__ import annotations

from typing import Any

from coral_operator.api import names
from coral_operator.api.names import API_VERSION, GROUP
from coral_operator.planning import naming


def build_executor_rbac(
    *, instance: str, namespace: str, instance_uid: str, system: str, robot: str
) -> list[dict[str, Any]]:
    """ServiceAccount, Role and RoleBinding of the executors on one robot."""
    name = naming.executor_account_name(instance)
    metadata = {
        "name": name,
        "namespace": namespace,
        "labels": {**naming.instance_labels(system, robot), names.LABEL_INSTANCE: instance},
        "ownerReferences": [naming.owner_reference(API_VERSION, names.INSTANCE_KIND, instance, instance_uid)],
    }
    return [
        {"apiVersion": "v1", "kind": "ServiceAccount", "metadata": dict(metadata)},
        {
            "apiVersion": "rbac.authorization.k8s.io/v1",
            "kind": "Role",
            "metadata": dict(metadata),
            "rules": [
                {
                    "apiGroups": [GROUP],
                    "resources": ["coralinstances/status"],
                    "resourceNames": [instance],
                    "verbs": ["patch"],
                }
            ],
        },
        {
            "apiVersion": "rbac.authorization.k8s.io/v1",
            "kind": "RoleBinding",
            "metadata": dict(metadata),
            "roleRef": {"apiGroup": "rbac.authorization.k8s.io", "kind": "Role", "name": name},
            "subjects": [{"kind": "ServiceAccount", "name": name, "namespace": namespace}],
        },
    ]
